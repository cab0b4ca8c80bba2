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
  libreaderwriterqueue-dev libboost-dev prometheus-cpp-dev
  can-utils iproute2
  clang libclang-rt-dev openssl clang-format clang-tidy   # clang-format, clang-tidy: tools/scripts/lint.sh
  python3 python3-matplotlib python3-numpy
  python3-canmatrix   # tests/io/dbc_canmatrix_diff.py: the DBC differential test (opt-in where missing)
  debhelper dpkg-dev help2man lintian
  libcivetweb-dev nlohmann-json3-dev libjs-chart.js   # torque-dash (HTTP/WebSocket server, JSON, page plots)
  libzstd-dev zlib1g-dev   # torque-dash MCAP recordings (zstd chunks, CRC32)
)
# Extra packages only the heavier test tiers need (VM for vcan, latency tools, foreign DDS peer, iceoryx RouDi
# for the shared-memory test, a real Prometheus server scraping the metrics endpoint).
if [[ "${TORQUED_DEPS_FULL:-1}" == "1" ]]; then
  PKGS+=(qemu-system-x86 busybox-static cpio rt-tests stress-ng libfastrtps-dev fastddsgen iceoryx prometheus curl)
  # torque-dash tests: Debian's Chromium (driven by playwright-core, no browser download) and Node.js/npm for
  # the Foxglove client (@foxglove/ws-protocol) and the MCAP reference reader (@mcap/core).
  PKGS+=(chromium nodejs)  # npm comes with the machine's Node.js (nodejs package)
fi

missing=()
for p in "${PKGS[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# npm packages of the torque-dash tests, into the project-local tools/dash/node_modules (in .gitignore), at the
# versions of tools/dash/package-lock.json; only when missing or older than the lock file.
npm_deps() {
  [[ "${TORQUED_DEPS_FULL:-1}" == "1" ]] || return 0
  local dir
  dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/../dash" && pwd)"
  command -v npm >/dev/null || return 0
  if [[ ! -f "$dir/node_modules/.package-lock.json" || "$dir/package-lock.json" -nt "$dir/node_modules/.package-lock.json" ]]; then
    echo "setup-deps: installing the torque-dash test packages (npm ci in $dir)"
    (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
  fi
}

# gpio-sim.ko for the test VM's kernel (tests/vm: the GPIO check), built from Debian's kernel source by
# tools/scripts/build-gpio-sim.sh; a failure is reported and leaves that one check skipping.
gpio_sim() {
  [[ "${TORQUED_DEPS_FULL:-1}" == "1" ]] || return 0
  bash "$(dirname "${BASH_SOURCE[0]}")/build-gpio-sim.sh" ||
    echo "setup-deps: WARNING: gpio-sim.ko not built (the VM check vm_gpio will skip); see the message above" >&2
}

if ((${#missing[@]} == 0)); then
  npm_deps
  gpio_sim
  exit 0
fi

echo "setup-deps: installing ${#missing[@]} package(s): ${missing[*]}"
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
npm_deps
gpio_sim
echo "setup-deps: done"
