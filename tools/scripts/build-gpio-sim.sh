#!/usr/bin/env bash
# Builds the gpio-sim kernel module (a simulated GPIO chip configured through configfs) for the test VM's kernel
# as an out-of-tree module, at set-up time (called by tools/scripts/setup-deps.sh; nothing is downloaded at
# build or test time). The VM (tests/vm/run_in_vm.sh) boots Debian 12's newest linux-image-6.1.0-*-rt-amd64;
# that kernel is built without CONFIG_GPIO_SIM and without CONFIG_IRQ_SIM (which gpio-sim selects), so the
# module is compiled from Debian's source package of exactly that kernel version:
#   drivers/gpio/gpio-sim.c + drivers/gpio/gpiolib.h (private header) + kernel/irq/irq_sim.c,
# linked into one gpio-sim.ko against linux-headers-<abi>-rt-amd64 (its Module.symvers: modversions).
# One change to irq_sim.c: its `handle_simple_irq(irq_to_desc(irq))` becomes `generic_handle_irq(irq)` (same
# flow handler, handle_simple_irq is what irq_sim installs on each of its interrupts) because irq_to_desc is not
# exported to modules by this kernel. Every other symbol the two files use is exported by vmlinux or
# configfs.ko (CONFIG_CONFIGFS_FS=m, loaded first).
#
#   tools/scripts/build-gpio-sim.sh [KERNEL_RELEASE]     e.g. 6.1.0-57-rt-amd64 (default: the newest one apt knows)
#
# Output: $TORQUED_GPIO_SIM_DIR (default /var/cache/torqued-vm/gpio-sim)/<release>/gpio-sim.ko and
# .../<release>/version (the Debian package version of the kernel, e.g. 6.1.192-3). Idempotent: does nothing
# when that module exists and was built by this script's current version. Exit 0 on success, 1 on failure
# (with the reason on stderr).
set -euo pipefail

out_root=${TORQUED_GPIO_SIM_DIR:-/var/cache/torqued-vm/gpio-sim}
die() { echo "build-gpio-sim: $*" >&2; exit 1; }

krel=${1:-}
if [[ -z "$krel" ]]; then
  # Same rule as tests/vm/run_in_vm.sh: the newest linux-image-6.1.0-*-rt-amd64-unsigned.
  pkg=$(apt-cache search --names-only '^linux-image-6\.1\.0-[0-9]+-rt-amd64-unsigned$' 2>/dev/null |
        awk '{print $1}' | sort -V | tail -1)
  [[ -n "$pkg" ]] || die "apt-cache knows no linux-image-6.1.0-*-rt-amd64-unsigned package (run apt-get update)"
  krel=${pkg#linux-image-}
  krel=${krel%-unsigned}
fi
pkg="linux-image-$krel-unsigned"
ver=$(apt-cache policy "$pkg" 2>/dev/null | awk '/Candidate:/ {print $2}')
[[ -n "$ver" && "$ver" != "(none)" ]] || die "apt knows no $pkg (cannot tell the kernel version)"
series=${krel%%-*}              # 6.1.0
series=${series%.*}             # 6.1
dest="$out_root/$krel"
stamp="$(sha1sum "$0" | cut -c1-16) $ver"
if [[ -f "$dest/gpio-sim.ko" && "$(cat "$dest/.stamp" 2>/dev/null)" == "$stamp" ]]; then
  exit 0
fi

# --- the kernel's headers and source, exactly the image's version --------------------------------------------
headers="linux-headers-$krel"
need=()
for p in "$headers" "linux-source-$series"; do
  q=$(dpkg-query -W -f='${Status} ${Version}' "$p" 2>/dev/null || true)
  [[ "$q" == "install ok installed $ver" ]] || need+=("$p=$ver")
done
SUDO=""
[[ $(id -u) -eq 0 ]] || SUDO="sudo"
if ((${#need[@]})); then
  echo "build-gpio-sim: installing ${need[*]}"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null ||
    die "apt-get install ${need[*]} failed"
fi
kdir="/usr/src/$headers"
src_tar="/usr/src/linux-source-$series.tar.xz"
[[ -f "$kdir/Module.symvers" ]] || die "$kdir/Module.symvers missing (package $headers incomplete?)"
[[ -f "$src_tar" ]] || die "$src_tar missing (package linux-source-$series)"

# --- build ------------------------------------------------------------------------------------------------------
work=$(mktemp -d /tmp/torqued-gpio-sim.XXXXXX)
trap 'rm -rf "$work"' EXIT
top="linux-source-$series"
tar -xJf "$src_tar" -C "$work" "$top/drivers/gpio/gpio-sim.c" "$top/drivers/gpio/gpiolib.h" \
  "$top/kernel/irq/irq_sim.c" || die "cannot extract gpio-sim.c/gpiolib.h/irq_sim.c from $src_tar"
m="$work/mod"
mkdir -p "$m"
cp "$work/$top/drivers/gpio/gpio-sim.c" "$m/gpio-sim-main.c"
cp "$work/$top/drivers/gpio/gpiolib.h" "$work/$top/kernel/irq/irq_sim.c" "$m/"
sed -i 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/' "$m/irq_sim.c"
grep -q 'generic_handle_irq(irqnum);' "$m/irq_sim.c" ||
  die "irq_sim.c of $ver does not contain the expected handle_simple_irq(irq_to_desc(irqnum)) line"
printf 'obj-m := gpio-sim.o\ngpio-sim-y := gpio-sim-main.o irq_sim.o\n' >"$m/Kbuild"
make -C "$kdir" M="$m" modules >"$work/make.log" 2>&1 || { tail -20 "$work/make.log" >&2; die "module build failed"; }
echo "$ver" >"$m/version"
echo "$stamp" >"$m/.stamp"
S=""
mkdir -p "$dest" 2>/dev/null && [[ -w "$dest" ]] || S=$SUDO   # /var/cache needs root
$S mkdir -p "$dest" && $S cp "$m/gpio-sim.ko" "$m/version" "$m/.stamp" "$dest/" || die "cannot write $dest"
echo "build-gpio-sim: $dest/gpio-sim.ko (kernel $krel, $ver)"
