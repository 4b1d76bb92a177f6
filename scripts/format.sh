#!/usr/bin/env bash
# clang-format over every C++ file of the repository (.clang-format: Google base, 110 columns).
# Usage: scripts/format.sh           reformat in place
#        scripts/format.sh --check   list the files that differ and exit 1 (scripts/test.sh runs it)
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v clang-format >/dev/null 2>&1; then
  echo "format: clang-format is not installed (scripts/install-deps.sh installs it)" >&2
  exit 1
fi
mapfile -t files < <(git ls-files '*.h' '*.cc' 2>/dev/null || find . -path ./build -prune -o \( -name '*.h' -o -name '*.cc' \) -print)
if [ "${1:-}" = --check ]; then
  bad=()
  for f in "${files[@]}"; do
    if ! clang-format --style=file "$f" | cmp -s - "$f"; then bad+=("$f"); fi
  done
  if [ ${#bad[@]} -gt 0 ]; then
    echo "format: ${#bad[@]} file(s) differ from clang-format (run scripts/format.sh): ${bad[*]}" >&2
    exit 1
  fi
  echo "format: ${#files[@]} files clang-format clean" >&2
else
  clang-format --style=file -i "${files[@]}"
fi
