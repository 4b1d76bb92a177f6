#!/usr/bin/env bash
# The README's main job, from a clean clone on Debian 12: installs the packages Waymark needs
# (scripts/install-deps.sh), builds it (scripts/build.sh), then runs `waymark demo` on the
# dataset shipped in data/demo (a rendered survey and a separate run through the same place):
#   detect the codes in the survey's images -> learn the map (Ceres) -> detect the run's codes
#   -> localize the run against the map (loosely coupled EKF, and ours) -> evaluate against the
#   ground truth, and print the accuracy table. Reports and plots go to OUT_DIR.
# Usage: scripts/demo.sh [OUT_DIR]   (default: out/demo in the source tree; a relative OUT_DIR
# is taken from the directory the script is run in).
# Nothing is deleted: `waymark demo` replaces only the files it writes (atomically), so other
# files in OUT_DIR are left alone (issue 18: `rm -rf OUT_DIR` wiped `scripts/demo.sh ~/robot`).
# WAYMARK_DEMO_SKIP_SETUP=1 skips the install and build; WAYMARK_DEMO_BINARY names the binary
# (tests use both).
set -euo pipefail
out=${1:-}
if [[ -n "$out" && "$out" != /* ]]; then out="$PWD/$out"; fi
cd "$(dirname "$0")/.."
out=${out:-out/demo}
if [[ -z "${WAYMARK_DEMO_SKIP_SETUP:-}" ]]; then
  scripts/install-deps.sh
  scripts/build.sh --target waymark
fi
"${WAYMARK_DEMO_BINARY:-./build/waymark}" demo --data data/demo --out "$out"
