#!/usr/bin/env bash
# Configures and builds Waymark in build/ (Release, Ninja; ccache when installed).
# Usage: scripts/build.sh [--target TARGET]... [extra cmake args]
#   no --target: everything (libraries, the binary, tests, benchmarks)
#   --target waymark: the binary alone (what the demo needs)
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
targets=()
while [ $# -gt 0 ] && [ "$1" = --target ]; do
  if [ $# -lt 2 ]; then
    echo "build.sh: --target needs a target name (e.g. --target waymark)" >&2
    exit 2
  fi
  targets+=(--target "$2")
  shift 2
done
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" >&2
cmake --build build -j "$jobs" "${targets[@]}" >&2
