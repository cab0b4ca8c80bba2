#!/bin/sh
# One vm_* or vm_sd_* ctest test: prints what its check printed inside the VM and returns its exit code.
#   vm_result.sh RESULTS_DIR CHECK
results=$1
name=$2
if [ -f "$results/SKIPPED" ]; then
  echo "SKIP vm check '$name': $(cat "$results/SKIPPED")"
  exit 77
fi
if [ ! -f "$results/$name.rc" ]; then
  echo "FAIL vm check '$name': no result (did its fixture test, vm_boot or vm_sd_boot, run and boot the VM?)"
  exit 1
fi
cat "$results/$name.log"
exit "$(cat "$results/$name.rc")"
