#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang, AddressSanitizer and UndefinedBehaviorSanitizer
# (build dir build-fuzz) and runs each for SECONDS (default 60), one after another, niced.
# Corpora: fuzz/corpus/<target>/ holds the seeds (from the tests and data/); what a run finds
# interesting goes to build-fuzz/corpus/<target>/, crashes and hangs to build-fuzz/findings/<target>/.
# Exits 1 when a target found a crash, a leak, a sanitizer report or a hang (> 60 s for one input:
# generous because the targets run niced on a shared machine, where 10 s flagged inputs that take
# 0.4 s of processor time).
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]   (targets: the names after fuzz_, e.g. map tum)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
scripts/install-deps.sh --fuzz
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DWAYMARK_FUZZ=ON -DWAYMARK_BUILD_TESTS=OFF -DWAYMARK_BUILD_BENCH=OFF "${launcher[@]}" >&2
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for f in fuzz/*_fuzz.cc; do n=${f#fuzz/}; targets+=("${n%_fuzz.cc}"); done
fi
jobs=$(nproc 2>/dev/null || echo 2)
cmake --build build-fuzz -j "$jobs" --target "${targets[@]/#/fuzz_}" >&2
failed=()
for t in "${targets[@]}"; do
  corpus=build-fuzz/corpus/$t findings=build-fuzz/findings/$t
  mkdir -p "$corpus" "$findings"
  seeds=()
  if [ -d "fuzz/corpus/$t" ]; then seeds=("fuzz/corpus/$t"); fi
  dict=()
  if [ -f "fuzz/dict/$t.dict" ]; then dict=(-dict="fuzz/dict/$t.dict"); fi
  echo "fuzz.sh: $t for $seconds s" >&2
  if ! nice -n 19 "build-fuzz/fuzz/fuzz_$t" "$corpus" "${seeds[@]}" "${dict[@]}" -max_total_time="$seconds" \
       -timeout=60 -rss_limit_mb=4096 -max_len=65536 -artifact_prefix="$findings/" -print_final_stats=1 \
       >"build-fuzz/fuzz-$t.log" 2>&1; then
    failed+=("$t")
    echo "fuzz.sh: $t FOUND a problem: build-fuzz/fuzz-$t.log, $findings/" >&2
  fi
  grep -E "^stat::number_of_executed_units|^Done [0-9]+ runs" "build-fuzz/fuzz-$t.log" >&2 || true
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: findings in ${failed[*]}" >&2
  exit 1
fi
echo "fuzz.sh: ${#targets[@]} targets clean, $seconds s each" >&2
