#!/usr/bin/env bash
# ctest fixture "vm": prepares the inputs on the host, boots ONE VM that runs every vcan check
# (tests/vm/vm_checks.sh), and leaves one <check>.rc / <check>.log per check in RESULTS for the vm_* tests.
#   vm_boot.sh BUILD_DIR RESULTS_DIR
# Inputs: data/demo/can.log + config/demo.dbc + data/demo/edges.csv when present, else a recording made here
# with torque-sim (deterministic). Exit 77 (skip) only when the VM cannot start at all (run_in_vm.sh says why).
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
build=$(cd "$1" && pwd)
results=$2
rm -rf "$results"
mkdir -p "$results/input"
results=$(cd "$results" && pwd)
in="$results/input"

# --- inputs -------------------------------------------------------------------------------------------------
if [[ -f "$repo/data/demo/can.log" && -f "$repo/data/demo/edges.csv" ]]; then
  cp "$repo/data/demo/can.log" "$repo/data/demo/edges.csv" "$in/"
  echo "vm_boot: inputs from data/demo"
elif [[ -x "$build/tools/torque-sim" ]]; then
  "$build/tools/torque-sim" -o "$in/sim" --write-dbc "$in/sim.dbc" >"$in/torque-sim.log" 2>&1 ||
    { cat "$in/torque-sim.log"; echo "vm_boot: torque-sim failed"; exit 1; }
  cp "$in/sim/can.log" "$in/sim/edges.csv" "$in/"
  echo "vm_boot: data/demo missing, inputs generated with torque-sim"
else
  echo "vm_boot: no data/demo/can.log and no torque-sim binary to make one"; exit 1
fi
if [[ -f "$repo/config/demo.dbc" ]]; then cp "$repo/config/demo.dbc" "$in/demo.dbc";
elif [[ -f "$in/sim.dbc" ]]; then cp "$in/sim.dbc" "$in/demo.dbc";
elif [[ -x "$build/tools/torque-sim" ]]; then "$build/tools/torque-sim" --write-dbc "$in/demo.dbc" -o "$in/dbc-only" >/dev/null 2>&1 || true; fi
"$build/tools/torque-canreplay" encode --edges "$in/edges.csv" -o "$in/encoder.log" --tick-ns 1 2>"$in/encode.txt" ||
  { cat "$in/encode.txt"; echo "vm_boot: torque-canreplay encode failed"; exit 1; }
cat "$in/encode.txt"

# --- one VM boot for all checks ------------------------------------------------------------------------------
"$here/run_in_vm.sh" --cache "$build/vm-cache" --out "$results" --timeout "${TORQUED_VM_TIMEOUT:-1200}" \
  --workdir "$repo" -- sh "$here/vm_checks.sh" "$build" "$in"
rc=$?
if ((rc == 77)); then
  echo "VM could not start; see the vm_boot output" >"$results/SKIPPED"
  exit 77
fi
echo "vm_boot: VM finished (guest exit $rc); per-check results in $results"
n=$(ls "$results"/*.rc 2>/dev/null | wc -l)
((n > 0)) || { echo "vm_boot: no check results came back from the VM"; exit 1; }
exit 0
