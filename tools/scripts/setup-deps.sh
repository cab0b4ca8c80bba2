#!/usr/bin/env bash
# Installs every Debian package torqued needs to build, test and run its demo.
# Idempotent: quiet when everything is present; runs `apt-get update` only when something is missing.
# Nothing is downloaded from anywhere but Debian's archive.
set -euo pipefail

PKGS=(
  build-essential cmake pkg-config ninja-build git ccache
  cyclonedds-dev cyclonedds-tools
  libeigen3-dev libspdlog-dev libfmt-dev libyaml-cpp-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libsystemd-dev systemd libgpiod-dev
  libreaderwriterqueue-dev libboost-dev
  can-utils iproute2
  clang libclang-rt-dev openssl
  python3 python3-matplotlib python3-numpy
)
# Extra packages only the heavier test tiers need (VM for vcan, latency tools, foreign DDS peer).
if [[ "${TORQUED_DEPS_FULL:-1}" == "1" ]]; then
  PKGS+=(qemu-system-x86 busybox-static cpio rt-tests stress-ng libfastrtps-dev fastddsgen)
fi

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  exit 0
fi

echo "setup-deps: installing ${#missing[@]} package(s): ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup-deps: done"
