#!/usr/bin/env bash
# Installs the Debian packages umbra builds and tests with (see
# ../shared/DEPENDENCIES.md). Does nothing when they are all present.
set -euo pipefail
packages=(
  cmake ninja-build g++ pkg-config python3
  libopenimageio-dev openimageio-tools libopenexr-dev libtbb-dev
  libcli11-dev nlohmann-json3-dev libfmt-dev zlib1g-dev libdeflate-dev libtiff-dev libpng-dev
  libgtest-dev libbenchmark-dev libembree-dev libre2-dev libosd-dev
  clang libclang-rt-14-dev
  chromium
  slurm-wlm munge
)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "umbra: installing ${missing[*]}"
  sudo_cmd=""
  [ "$(id -u)" -ne 0 ] && sudo_cmd="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo_cmd apt-get update -q
  $sudo_cmd apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
