#!/usr/bin/env bash
# ctest fixture "vm_sd": boots ONE VM with systemd as PID 1 (run_in_vm.sh --systemd: copy-on-write overlay of the
# host root) that installs the Debian package and runs every service check (tests/vm/vm_sd_checks.sh), leaving
# one <check>.rc / <check>.log per check in RESULTS for the vm_sd_* tests.
#   vm_sd_boot.sh BUILD_DIR RESULTS_DIR
# The package: BUILD_DIR/deb/torqued_*_<arch>.deb (ctest deb_build, or tools/scripts/build-deb.sh).
# Exit 77 (skip) when no package was built or the VM cannot start at all (run_in_vm.sh says why).
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "$1" && pwd)
results=$2
rm -rf "$results"
mkdir -p "$results"
results=$(cd "$results" && pwd)
skip() { echo "vm_sd_boot: SKIP: $*"; echo "$*" >"$results/SKIPPED"; exit 77; }

debs=("$build"/deb/torqued_*_"$(dpkg --print-architecture)".deb)
deb=${debs[0]}
[[ -f "$deb" ]] || skip "no torqued_*.deb in $build/deb (ctest deb_build or tools/scripts/build-deb.sh)"
echo "vm_sd_boot: package $deb"

t0=$SECONDS
"$here/run_in_vm.sh" --systemd --cache "$build/vm-cache" --out "$results" --timeout "${TORQUED_VM_TIMEOUT:-900}" \
  --workdir / -- bash "$here/vm_sd_checks.sh" "$deb"
rc=$?
((rc == 77)) && skip "VM could not start; see the vm_sd_boot output"
echo "vm_sd_boot: VM finished in $((SECONDS - t0)) s (guest exit $rc); per-check results in $results"
n=$(find "$results" -maxdepth 1 -name '*.rc' | wc -l)
((n > 0)) || { echo "vm_sd_boot: no check results came back from the VM"; exit 1; }
exit 0
