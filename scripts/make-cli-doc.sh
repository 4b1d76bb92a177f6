#!/usr/bin/env bash
# Regenerates docs/cli.md from the binary's own help text.
# Usage: scripts/make-cli-doc.sh [BINARY]   (default: build/waymark)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build/waymark}
out=docs/cli.md
tmp=$(mktemp "$out.XXXXXX")
trap 'rm -f "$tmp"' EXIT
{
  echo "# waymark command-line reference"
  echo
  echo "Generated from the binary's own help (\`waymark help\`, \`waymark <command> --help\`) by"
  echo "\`scripts/make-cli-doc.sh\`; every command writes results to files or stdout, logs and progress to"
  echo "stderr, prints one line and exits non-zero on error, and writes nothing partial."
  echo
  echo '```'
  "$waymark" help
  echo '```'
  # Command names are the first 12 columns of the list (a name may hold a space: "map score").
  "$waymark" help | sed -n 's/^  \(.\{12\}\).*/\1/p' | sed 's/ *$//' | grep -v '^help$' |
    while IFS= read -r name; do
      echo
      echo "## waymark $name"
      echo
      echo '```'
      # shellcheck disable=SC2086
      "$waymark" help $name
      echo '```'
    done
} > "$tmp"
mv "$tmp" "$out"
trap - EXIT
echo "wrote $out" >&2
