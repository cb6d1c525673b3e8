#!/usr/bin/env bash
# The demo: installs what is missing, builds, and runs the main job on the simulated rig.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
./build/tools/strut demo "$@"
