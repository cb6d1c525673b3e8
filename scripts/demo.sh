#!/usr/bin/env bash
# The demo: installs what is missing, builds, and runs the main job on the simulated rig on a drawn
# unit (docs/demo.md). Each run writes to a fresh folder (strut-demo, strut-demo-2, ...); options
# are passed on to `strut demo` (e.g. --unit 7 for another damper).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
./build/tools/strut demo "$@"
