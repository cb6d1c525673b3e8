#!/usr/bin/env bash
# Builds the CAN decoder's libFuzzer target with clang-14 (AddressSanitizer and
# UndefinedBehaviorSanitizer) and runs it: scripts/fuzz-can.sh [RUNS] [BUILD_DIR].
# docs/can-acquisition.md, "Tests and fuzzing". Exit code non-zero on a crash or a broken invariant.
set -euo pipefail
runs="${1:-1000000}"
out="${2:-build-fuzz}"
root="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
binary="$out/can_decoder_fuzz"
clang++-14 -std=c++20 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -I "$root/daq/include" \
  "$root/daq/fuzz/can_decoder_fuzz.cpp" "$root/daq/src/can_acquisition.cpp" "$root/daq/src/can_transport.cpp" \
  "$root/daq/src/acquisition.cpp" -lfmt -o "$binary"
mkdir -p "$out/can-corpus"
"$binary" -runs="$runs" -max_len=4096 -seed=1 -print_final_stats=1 "$out/can-corpus"
