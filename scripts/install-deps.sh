#!/usr/bin/env bash
# Installs the Debian 12 packages Waymark builds and runs with. Idempotent: packages
# already installed are skipped, and nothing is asked of apt when all are present.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libceres-dev
  libopencv-dev libopencv-contrib-dev
  libdmtx-dev libzxing-dev libapriltag-dev
  libyaml-cpp-dev nlohmann-json3-dev libre2-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang-format
)
# scripts/install-deps.sh --fuzz adds what scripts/fuzz.sh needs: clang with its sanitizer
# and libFuzzer runtimes (docs/reliability.md). Not part of the default install.
if [[ "${1:-}" == "--fuzz" ]]; then
  packages+=(clang libclang-rt-14-dev libfuzzer-14-dev)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed" >&2
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
