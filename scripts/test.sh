#!/usr/bin/env bash
# Installs dependencies, builds, and runs the whole test suite through ctest.
#   scripts/test.sh              clang-format check, Release build in build/ (-Werror), every test
#   scripts/test.sh --sanitize   the same suite built with AddressSanitizer and
#                                UndefinedBehaviorSanitizer in build-sanitize/ (docs/reliability.md):
#                                any sanitizer report fails its test
# Extra arguments after --sanitize go to ctest (e.g. -R '^(io|cli)/' to run a part).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
if [[ "${1:-}" == "--sanitize" ]]; then
  shift
  # Leaks are findings too; a report aborts the test (halt_on_error), so ctest sees it fail.
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:abort_on_error=1:strict_string_checks=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  launcher=()
  if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
  cmake -S . -B build-sanitize -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWAYMARK_SANITIZE=ON \
    -DWAYMARK_WERROR=ON -DWAYMARK_BUILD_BENCH=OFF "${launcher[@]}" >&2
  cmake --build build-sanitize -j "$jobs" >&2
  # Sanitized code runs 2-5x slower: the per-test timeout is scaled.
  ctest --test-dir build-sanitize --output-on-failure -j "$jobs" "$@"
  exit 0
fi
scripts/format.sh --check
scripts/build.sh -DWAYMARK_WERROR=ON
ctest --test-dir build --output-on-failure -j "$jobs"
