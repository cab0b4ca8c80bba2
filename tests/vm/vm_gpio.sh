#!/bin/sh
# Runs inside the test VM (tests/vm/run_in_vm.sh, chrooted into the host root): loads configfs.ko (from the VM
# kernel's module tree, $TORQUED_VM_MODULES) and gpio-sim.ko (built at set-up time for this kernel by
# tools/scripts/build-gpio-sim.sh), creates a simulated GPIO chip through configfs (label torqued-crank,
# 4 lines), runs tests/vm/vm_gpio_check on its line 0, and removes the chip again.
#   vm_gpio.sh BUILD_DIR [vm_gpio_check options...]
# Exit 77 (skip) with the reason when the module was not built for this kernel; other failures are errors.
build=$1
shift
krel=$(uname -r)
dir=${TORQUED_GPIO_SIM_DIR:-/var/cache/torqued-vm/gpio-sim}/$krel
ko=$dir/gpio-sim.ko
if [ ! -f "$ko" ]; then
  echo "SKIP gpio: no $ko for the VM kernel $krel (tools/scripts/setup-deps.sh builds it with" \
       "tools/scripts/build-gpio-sim.sh)"
  exit 77
fi
ver=$(cat "$dir/version" 2>/dev/null)
if [ -z "$ver" ] || ! grep -q " $ver " /proc/version; then
  echo "SKIP gpio: $ko was built for kernel package version '$ver', the VM runs: $(cat /proc/version)" \
       "(rerun tools/scripts/build-gpio-sim.sh $krel)"
  exit 77
fi
modules=${TORQUED_VM_MODULES:-$build/vm-cache/kernel/lib/modules/$krel}
# dmesg holds everything since the VM booted (vm_checks.sh ran other checks before this one): judge only the
# kernel lines logged from here on.
dmesg_before=$(dmesg | wc -l)
if ! grep -q '^configfs ' /proc/modules && ! grep -q configfs /proc/filesystems; then
  busybox insmod "$modules/kernel/fs/configfs/configfs.ko" || { echo "FAIL gpio: insmod configfs.ko"; exit 1; }
fi
if ! grep -q '^gpio_sim ' /proc/modules; then
  busybox insmod "$ko" || { echo "FAIL gpio: insmod $ko"; dmesg | tail -5; exit 1; }
fi
echo "PASS gpio: gpio-sim.ko ($ver) loaded into $krel"
grep -q ' /sys/kernel/config ' /proc/mounts || mount -t configfs configfs /sys/kernel/config ||
  { echo "FAIL gpio: mount configfs"; exit 1; }
cfg=/sys/kernel/config/gpio-sim/torqued
mkdir "$cfg" "$cfg/bank0" && echo 4 >"$cfg/bank0/num_lines" && echo torqued-crank >"$cfg/bank0/label" &&
  echo 1 >"$cfg/live" || { echo "FAIL gpio: creating the chip through configfs ($cfg)"; dmesg | tail -5; exit 1; }
dev=$(cat "$cfg/dev_name")
chip=$(cat "$cfg/bank0/chip_name")
pull=/sys/devices/platform/$dev/$chip/sim_gpio0/pull
echo "PASS gpio: chip $chip (label torqued-crank) of $dev is live; line 0 driven through $pull"
"$build/tests/vm/vm_gpio_check" --chip torqued-crank --pull "$pull" "$@"
rc=$?
echo 0 >"$cfg/live" && rmdir "$cfg/bank0" "$cfg" || { echo "FAIL gpio: removing the chip"; rc=1; }
if dmesg | tail -n +$((dmesg_before + 1)) | grep -q -i 'WARNING:\|BUG:'; then
  echo "FAIL gpio: kernel warnings:"
  dmesg | tail -n +$((dmesg_before + 1)) | grep -i -A3 'WARNING:\|BUG:' | head -20; rc=1
fi
exit $rc
