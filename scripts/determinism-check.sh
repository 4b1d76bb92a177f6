#!/usr/bin/env bash
# Issue 14's first done-when, shown: the same images give byte-identical detections files on an
# idle machine and beside a full-load build, at any --threads (docs/detection.md "Determinism").
#
#   1. Images: DIR if given, else 150 issue frames rendered by
#      `bench_recall_bench --frames 150 --seed 1 --scenario issue --dump all --dump-dir D`.
#   2. Idle: `waymark detect DIR` at --threads 1, --threads 2 and the default (the machine's cores),
#      and one `waymark map build data/demo/survey --detect-images`.
#   3. Loaded: a real compile of this project (a scratch build directory, ccache off,
#      -j$(nproc)) is started; once it compiles, the same four runs; the script checks that the
#      build is still running after the last run (else the runs were not all beside it: exit 2),
#      prints the load average after each run, then stops the build.
#   4. Every detections file and both map.json files are compared with cmp (detections against the
#      idle --threads 1 file). Exit 0 only when all are identical, 1 when one differs.
#
# Usage: scripts/determinism-check.sh [DIR]    (run from anywhere)
# Environment: BUILD (default build: waymark and bench/bench_recall_bench are taken from it),
#              KEEP=1 keeps the scratch directory (its path is printed).
# Takes about 5 minutes on 2 cores (the 150 renders, six detect runs, two map builds, and a minute
# for the load build to get going).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${BUILD:-build}
waymark=$(realpath "$build/waymark")
[ -x "$waymark" ] || { echo "determinism-check: no $build/waymark (build it first)" >&2; exit 2; }

# Every process below $1 (its children, theirs, and so on).
descendants() {
  local p
  for p in $(pgrep -P "$1"); do
    echo "$p"
    descendants "$p"
  done
}
# How many compilers of the load build run now.
compilers() {
  local n=0 p
  for p in $(descendants "$load_pid"); do
    [ "$(cat "/proc/$p/comm" 2>/dev/null)" = cc1plus ] && n=$((n + 1))
  done
  echo "$n"
}

work=$(mktemp -d "${TMPDIR:-/tmp}/determinism.XXXXXX")
load_pid=""
stop_load() {
  if [ -n "$load_pid" ] && kill -0 "$load_pid" 2>/dev/null; then
    local procs
    procs=$(descendants "$load_pid")
    # The build's process group (set -m below): its shell and ninja; ninja stops its compilers
    # (each in a process group of its own) on SIGTERM; whatever is left of them is ended here.
    kill -TERM -- "-$load_pid" 2>/dev/null || true
    wait "$load_pid" 2>/dev/null || true
    sleep 1
    for p in $procs; do kill -TERM "$p" 2>/dev/null || true; done
  fi
  load_pid=""
}
cleanup() {
  stop_load
  if [ "${KEEP:-0}" = 1 ]; then echo "kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

if [ $# -ge 1 ]; then
  images=$(realpath "$1")
  [ -d "$images" ] || { echo "determinism-check: $1 is not a directory" >&2; exit 2; }
  echo "images: $images"
else
  bench="$build/bench/bench_recall_bench"
  [ -x "$bench" ] || { echo "determinism-check: no $bench (configure with -DWAYMARK_BUILD_BENCH=ON)" >&2; exit 2; }
  images="$work/frames"
  mkdir "$images"
  "$bench" --frames 150 --seed 1 --scenario issue --no-write --dump all --dump-dir "$images" > "$work/render.log"
  echo "images: 150 issue frames (bench_recall_bench --frames 150 --seed 1 --scenario issue --dump all)"
fi
echo "binary: $waymark; $(nproc) cores; scratch: $work"

# The load averages (1, 5, 15 min) and, beside the load build, how many of its compilers run now.
load() {
  local compilers=""
  [ -z "$load_pid" ] || compilers="; load build compilers running: $(compilers)"
  echo "$(cut -d' ' -f1-3 /proc/loadavg)$compilers"
}

# run PHASE: the three detect runs and the map build, outputs named after PHASE.
run() {
  local phase=$1 t
  for t in 1 2 default; do
    local threads=()
    [ "$t" = default ] || threads=(--threads "$t")
    "$waymark" detect "$images" --out "$work/$phase-t$t.jsonl" "${threads[@]}" > "$work/$phase-t$t.log" 2>&1
    echo "  $phase detect --threads $t: $(tail -n 1 "$work/$phase-t$t.log" | sed 's/^detect: //'); load average $(load)"
  done
  "$waymark" map build "$root/data/demo/survey" --detect-images --out "$work/$phase-map.json" \
    > "$work/$phase-map.log" 2>&1
  echo "  $phase map build data/demo/survey --detect-images: done; load average $(load)"
}

echo "idle runs (load average before: $(load))"
run idle

# The load: a real compile of the project in a scratch build directory, no compiler cache.
echo "starting the load: cmake + ninja -j$(nproc) of this project in $work/load-build (CCACHE_DISABLE=1)"
# In this session (so in the same scheduler autogroup as the runs, which a setsid would leave it
# out of: the kernel then shares the cores between the two groups, not between the processes), in
# a process group of its own (set -m) so that it can be stopped as one.
set -m
bash -c "cd '$root' && CCACHE_DISABLE=1 cmake -S . -B '$work/load-build' -G Ninja \
  -DCMAKE_BUILD_TYPE=Release -DWAYMARK_BUILD_BENCH=ON > '$work/load-build.log' 2>&1 && \
  CCACHE_DISABLE=1 ninja -C '$work/load-build' -j$(nproc) >> '$work/load-build.log' 2>&1" &
load_pid=$!
set +m
# Wait until the build compiles (cmake's configure step is light), at most 5 minutes.
for _ in $(seq 300); do
  if [ "$(compilers)" -gt 0 ]; then break; fi
  kill -0 "$load_pid" 2>/dev/null || { echo "determinism-check: the load build ended early:" >&2; tail -n 5 "$work/load-build.log" >&2; exit 2; }
  sleep 1
done
[ "$(compilers)" -gt 0 ] || { echo "determinism-check: the load build did not start compiling" >&2; exit 2; }
sleep 60  # let the 1-minute load average climb
echo "loaded runs (load average before: $(load))"
run loaded
if ! kill -0 "$load_pid" 2>/dev/null || [ -z "$(descendants "$load_pid")" ]; then
  echo "determinism-check: the load build was no longer compiling after the loaded runs" >&2
  exit 2
fi
echo "the load build was still compiling after the loaded runs ($(grep -c '^\[' "$work/load-build.log") of its steps done); stopping it"
stop_load

status=0
compare() {
  if cmp -s "$1" "$2"; then
    echo "  identical: ${1#"$work"/} ${2#"$work"/}"
  else
    echo "  DIFFERENT: ${1#"$work"/} ${2#"$work"/} ($(cmp "$1" "$2" 2>&1 | head -n 1))"
    status=1
  fi
}
echo "comparisons (cmp)"
for phase in idle loaded; do
  for t in 1 2 default; do
    [ "$phase-t$t" = idle-t1 ] || compare "$work/idle-t1.jsonl" "$work/$phase-t$t.jsonl"
  done
done
compare "$work/idle-map.json" "$work/loaded-map.json"
echo "markers in idle-t1.jsonl: $(grep -o '"id"' "$work/idle-t1.jsonl" | wc -l)"
if [ "$status" = 0 ]; then echo "determinism-check: all identical"; else echo "determinism-check: FAILED"; fi
exit "$status"
