#!/usr/bin/env bash
# Configures and builds strut (Release) into build/. Installs missing dependencies first.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DSTRUT_REQUIRE_POSTGRES="${STRUT_REQUIRE_POSTGRES:-OFF}" >/dev/null
cmake --build build --parallel "$(nproc)"
