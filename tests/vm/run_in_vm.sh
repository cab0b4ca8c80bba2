#!/usr/bin/env bash
# Runs one command inside a throw-away qemu VM whose kernel has SocketCAN + vcan (this machine's kernel has
# no CAN). The guest sees the host's root file system read-only over 9p (so the build tree's binaries and the
# repository's data are at their usual paths), a tmpfs on /tmp, a writable share of a host directory at
# $TORQUED_VM_OUT (= /tmp/vm-out), and an interface vcan0 that is up.
#
#   tests/vm/run_in_vm.sh [--cache DIR] [--out DIR] [--timeout SEC] [--workdir DIR] [--systemd] -- COMMAND [ARGS...]
#
#   --cache DIR   where the Debian kernel package, its extracted tree and the initramfs are kept
#                 (default: <repo>/build/vm-cache; never committed)
#   --out DIR     host directory the guest may write to (default: a temporary directory, removed afterwards)
#   --timeout S   wall-clock limit for the whole VM run (default 600 s; TCG is slow)
#   --workdir D   working directory of COMMAND inside the guest (default: the current directory)
#   --systemd     systemd as PID 1 instead of a chroot: the root is a copy-on-write overlay (overlayfs: the
#                 read-only 9p host root under a tmpfs, so the guest may install packages; nothing reaches the
#                 host), COMMAND runs as the unit torqued-vm-test.service of the boot target
#                 torqued-vm-test.target (basic.target plus that unit; the host's enabled services are masked),
#                 then the guest powers off. No vcan0 in this mode. Units it may need to change before it starts
#                 (drop-ins) are COMMAND's to write: systemd reloads them when asked.
#
# The command's output goes to the serial console between markers; this script prints it and exits with the
# command's exit code. Exit code 77 (ctest SKIP_RETURN_CODE) only when the VM cannot start at all: no qemu
# binary, or the kernel package cannot be obtained. Any other failure (boot, module load, time-out) is an error.
#
# Recipe (Debian 12): linux-image-6.1.0-*-rt-amd64-unsigned fetched with `apt-get download`, extracted with
# dpkg-deb -x; a busybox-static initramfs insmods the virtio/9p/CAN modules (uncompressed .ko in that package),
# mounts the host root, creates vcan0 and chroots. qemu -accel tcg (KVM is not usable here), -nic none (no network
# card: the guest has only lo and vcan0).
set -euo pipefail

SKIP=77
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
cache="$repo/build/vm-cache"
out=""
timeout_s=600
workdir=$(pwd)
systemd=0

while (($#)); do
  case "$1" in
    --cache) cache=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --timeout) timeout_s=$2; shift 2 ;;
    --workdir) workdir=$2; shift 2 ;;
    --systemd) systemd=1; shift ;;
    --) shift; break ;;
    -h|--help) sed -n '2,27p' "$0"; exit 0 ;;
    *) echo "run_in_vm: unknown option '$1' (expected --cache/--out/--timeout/--workdir/--systemd, then -- COMMAND)" >&2; exit 2 ;;
  esac
done
if (($# == 0)); then
  echo "run_in_vm: no command given (usage: run_in_vm.sh [options] -- COMMAND [ARGS...])" >&2
  exit 2
fi

skip() { echo "run_in_vm: SKIP: $*" >&2; exit $SKIP; }
die() { echo "run_in_vm: ERROR: $*" >&2; exit 1; }

qemu=$(command -v qemu-system-x86_64 || true)
[[ -n "$qemu" ]] || skip "qemu-system-x86_64 not installed (tools/scripts/setup-deps.sh installs qemu-system-x86)"
busybox=/bin/busybox
[[ -x "$busybox" ]] && ! ldd "$busybox" >/dev/null 2>&1 || skip "static /bin/busybox not found (install busybox-static)"
command -v cpio >/dev/null || skip "cpio not installed"

mkdir -p "$cache"
cache=$(cd "$cache" && pwd)

# --- 1. kernel: newest linux-image-6.1.0-*-rt-amd64-unsigned, downloaded once into the cache -----------------
exec 9>"$cache/.lock"
flock 9   # parallel callers share the cache
kroot="$cache/kernel"
if [[ ! -f "$kroot/.ok" ]]; then
  deb=$(ls "$cache"/linux-image-6.1.0-*-rt-amd64-unsigned_*.deb 2>/dev/null | sort -V | tail -1 || true)
  if [[ -z "$deb" ]]; then
    pkg=$(apt-cache search --names-only '^linux-image-6\.1\.0-[0-9]+-rt-amd64-unsigned$' 2>/dev/null |
          awk '{print $1}' | sort -V | tail -1)
    [[ -n "$pkg" ]] || skip "apt-cache knows no linux-image-6.1.0-*-rt-amd64-unsigned package (run apt-get update)"
    echo "run_in_vm: fetching $pkg (once, into $cache)" >&2
    (cd "$cache" && apt-get download "$pkg" >/dev/null 2>"$cache/apt-download.log") ||
      skip "apt-get download $pkg failed: $(tail -1 "$cache/apt-download.log")"
    deb=$(ls "$cache"/linux-image-6.1.0-*-rt-amd64-unsigned_*.deb | sort -V | tail -1)
  fi
  rm -rf "$kroot"
  dpkg-deb -x "$deb" "$kroot" || die "dpkg-deb -x $deb failed"
  touch "$kroot/.ok"
fi
vmlinuz=$(ls "$kroot"/boot/vmlinuz-* | head -1)
moddir=$(ls -d "$kroot"/lib/modules/* | head -1)

# --- 2. base initramfs (busybox + modules + init), rebuilt when this script changes --------------------------
modules=(virtio virtio_ring virtio_pci_modern_dev virtio_pci_legacy_dev virtio_pci netfs fscache 9pnet
         9pnet_virtio 9p can can-raw can-dev vcan)
sd_modules=(overlay)   # loaded only with --systemd
base="$cache/base-initramfs.cpio"
stamp="$(sha1sum "$0" | cut -c1-16)-$(basename "$moddir")"
if [[ ! -f "$base" || "$(cat "$base.stamp" 2>/dev/null)" != "$stamp" ]]; then
  ir="$cache/initramfs"
  rm -rf "$ir"
  mkdir -p "$ir"/{bin,dev,proc,sys,mnt/host,lib/modules}
  cp "$busybox" "$ir/bin/busybox"
  # Load order: each module after the modules named in its `depends=` modinfo field (e.g. virtio needs
  # virtio_ring in this kernel), dependencies not in the list are pulled in too.
  order=()
  add_module() {
    local m=$1 ko d
    [[ " ${order[*]} " == *" $m "* ]] && return 0
    ko=$(find "$moddir/kernel" \( -name "$m.ko" -o -name "${m//-/_}.ko" -o -name "${m//_/-}.ko" \) | head -1)
    [[ -n "$ko" ]] || die "module $m.ko not found under $moddir"
    for d in $(strings -a "$ko" | sed -n 's/^depends=//p' | tr ',' ' '); do add_module "$d"; done
    cp "$ko" "$ir/lib/modules/$m.ko"
    order+=("$m")
  }
  for m in "${modules[@]}"; do add_module "$m"; done
  n_base=${#order[@]}
  for m in "${sd_modules[@]}"; do add_module "$m"; done
  cat >"$ir/init" <<'EOF'
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
fail() { echo "@@TORQUED_VM_ERROR $*@@"; echo "@@TORQUED_VM_EXIT=125@@"; poweroff -f; }
for m in $(cat /modules.list); do
  insmod /lib/modules/$m.ko || fail "insmod $m"
done
mount -t 9p -o trans=virtio,version=9p2000.L,ro,msize=512000,cache=loose hostroot /mnt/host || fail "mount hostroot"
H=/mnt/host
if [ -d /sd ]; then  # --systemd: overlay root (host root read-only below, tmpfs above), systemd as PID 1
  for m in $(cat /sd-modules.list); do insmod /lib/modules/$m.ko || fail "insmod $m"; done
  mkdir -p /mnt/rw /mnt/root
  mount -t tmpfs -o mode=0755 tmpfs /mnt/rw && mkdir -p /mnt/rw/upper /mnt/rw/work || fail "mount the upper tmpfs"
  R=/mnt/root
  mount -t overlay overlay -o lowerdir=$H,upperdir=/mnt/rw/upper,workdir=/mnt/rw/work $R || fail "mount overlay root"
  cp -a /sd/. $R/ || fail "copy the test units into the overlay root"
  # Not a container: the host root may carry docker's/podman's marker, and systemd would then ignore the
  # kernel command line (systemd.unit=) and run as in a container.
  rm -f $R/.dockerenv $R/run/.containerenv
  mkdir -p $R/tmp/vm-out
  mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000 vmout $R/tmp/vm-out || fail "mount vm-out share"
  for d in dev proc sys; do mount --move /$d $R/$d || fail "move /$d"; done
  exec switch_root $R /lib/systemd/systemd
  fail "switch_root to systemd"
fi
mount -t proc proc $H/proc && mount -t sysfs sys $H/sys && mount -o bind /dev $H/dev || fail "mount proc/sys/dev"
# A writable /tmp must not hide the host's /tmp: checkouts and build trees often live there (CI clones into
# /tmp). Keep the host's /tmp reachable under /run/hosttmp and link each of its entries into the new tmpfs.
mount -t tmpfs tmpfs $H/run || fail "mount /run"
mkdir -p $H/run/hosttmp && mount -o bind $H/tmp $H/run/hosttmp || fail "bind host /tmp"
mount -t tmpfs tmpfs $H/tmp || fail "mount /tmp"
for e in $(ls -A $H/run/hosttmp); do ln -s "/run/hosttmp/$e" "$H/tmp/$e"; done
mkdir -p $H/tmp/vm-out $H/dev/shm && mount -t tmpfs tmpfs $H/dev/shm
mount -t 9p -o trans=virtio,version=9p2000.L,msize=512000 vmout $H/tmp/vm-out || fail "mount vm-out share"
cp /run.sh $H/tmp/torqued-vm-run.sh
ip link add dev vcan0 type vcan || fail "ip link add vcan0"
ip link set vcan0 up || fail "ip link set vcan0 up"
echo "@@TORQUED_VM_BEGIN@@"
chroot $H /bin/sh /tmp/torqued-vm-run.sh </dev/null 2>&1
rc=$?
echo "@@TORQUED_VM_EXIT=$rc@@"
sync
umount $H/tmp/vm-out 2>/dev/null
umount $H/run/hosttmp 2>/dev/null
poweroff -f
EOF
  chmod +x "$ir/init"
  printf '%s\n' "${order[@]:0:n_base}" >"$ir/modules.list"
  printf '%s\n' "${order[@]:n_base}" >"$ir/sd-modules.list"
  (cd "$ir" && find . | cpio -o -H newc --quiet) >"$base.tmp"
  mv "$base.tmp" "$base"
  echo "$stamp" >"$base.stamp"
fi
exec 9>&-

# --- 3. per-run initramfs: base + /run.sh (concatenated cpio archives) ------------------------------------
tmp=$(mktemp -d /tmp/torqued-vm.XXXXXX)
own_out=0
if [[ -z "$out" ]]; then out="$tmp/out"; own_out=1; fi
mkdir -p "$out"
out=$(cd "$out" && pwd)
cleanup() { [[ -n "${TORQUED_VM_KEEP:-}" ]] && { echo "run_in_vm: kept $tmp" >&2; return; }; if ((own_out)); then rm -rf "$tmp"; else rm -rf "$tmp"/{run.sh,run.cpio,initrd,console.log,console.log.txt,sd}; rmdir "$tmp" 2>/dev/null || true; fi; }
trap cleanup EXIT
{
  echo "export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
  echo "export HOME=/tmp TORQUED_VM=1 TORQUED_VM_OUT=/tmp/vm-out"
  printf 'export TORQUED_VM_MODULES=%q\n' "$moddir"   # the guest kernel's module tree (host path, seen over 9p)
  printf 'cd %q || exit 126\n' "$workdir"
  printf 'exec'; printf ' %q' "$@"; printf '\n'
} >"$tmp/run.sh"
files=(run.sh)
append="console=ttyS0 quiet loglevel=3 panic=-1 oops=panic"
mem=1024
if ((systemd)); then
  # Files copied into the overlay root before systemd starts (/sd in the initramfs): the boot target, the unit
  # that runs COMMAND (markers on the console, then power off), masks of what would only slow the boot.
  sd="$tmp/sd"
  units="$sd/etc/systemd/system"
  install -d -m 0755 "$units" "$sd/etc/torqued-vm" "$sd/etc/tmpfiles.d"
  cat >"$sd/etc/torqued-vm/run.sh" <<'EOF'
echo "@@TORQUED_VM_BEGIN@@"
(. /etc/torqued-vm/command.sh) 2>&1
rc=$?
echo "@@TORQUED_VM_EXIT=$rc@@"
sync
systemctl poweroff --force --force
EOF
  mv "$tmp/run.sh" "$sd/etc/torqued-vm/command.sh"
  cat >"$units/torqued-vm-test.target" <<'EOF'
[Unit]
Description=run_in_vm.sh --systemd: the basic system and the test command, nothing else
Requires=basic.target torqued-vm-test.service
After=basic.target
AllowIsolate=yes
EOF
  cat >"$units/torqued-vm-test.service" <<'EOF'
[Unit]
Description=run_in_vm.sh --systemd: the test command (powers the VM off when done)
After=basic.target

[Service]
Type=oneshot
ExecStart=/bin/sh /etc/torqued-vm/run.sh
StandardInput=null
StandardOutput=tty
StandardError=tty
TTYPath=/dev/console
TTYReset=no
TTYVHangup=no
TimeoutStartSec=infinity
EOF
  # Masked (linked to /dev/null): everything the host enables (databases, timers, time sync, gettys) and the
  # first-boot wizard; /tmp keeps the host's entries (a checkout may live there): no clean-up of /tmp at boot.
  shopt -s nullglob
  for u in /etc/systemd/system/*.wants/* getty@.service serial-getty@.service console-getty.service \
           systemd-firstboot.service systemd-timesyncd.service systemd-networkd.service \
           systemd-networkd-wait-online.service systemd-logind.service; do
    ln -sfn /dev/null "$units/$(basename "$u")"
  done
  shopt -u nullglob
  ln -sfn /dev/null "$sd/etc/tmpfiles.d/tmp.conf"
  files=(sd)
  append+=" systemd.unit=torqued-vm-test.target systemd.show_status=false systemd.log_level=warning"
  append+=" systemd.firstboot=off"
  mem=1536
fi
(cd "$tmp" && find "${files[@]}" | cpio -o -H newc --quiet) >"$tmp/run.cpio"
cat "$base" "$tmp/run.cpio" >"$tmp/initrd"

# --- 4. boot ------------------------------------------------------------------------------------------------
log="$tmp/console.log"
set +e
# -nic none: the guest gets no network card at all (qemu's default is a user-mode NIC routed to the host's
# network); the tests need only lo and vcan0, and nothing a VM run does may leave the machine.
timeout --kill-after=10 "$timeout_s" "$qemu" -accel tcg -m "$mem" -smp 2 -nographic -no-reboot -nic none \
  -kernel "$vmlinuz" -initrd "$tmp/initrd" \
  -append "$append" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
  -virtfs local,path="$out",mount_tag=vmout,security_model=none,multidevs=remap \
  </dev/null >"$log" 2>&1
qrc=$?
set -e
tr -d '\r' <"$log" >"$log.txt"
if ((qrc == 124 || qrc == 137)); then
  sed -n '/@@TORQUED_VM_BEGIN@@/,$p' "$log.txt" | tail -n +2
  die "VM did not finish within ${timeout_s}s (last console lines above)"
fi
if ! grep -q '@@TORQUED_VM_EXIT=' "$log.txt"; then
  tail -40 "$log.txt" >&2
  if ! grep -q 'Linux version\|Run /init\|@@TORQUED' "$log.txt" && ((qrc != 0)); then
    skip "qemu could not start (exit $qrc): $(head -3 "$log.txt" | tr '\n' ' ')"
  fi
  die "VM ended without an exit marker (qemu exit $qrc); console tail above"
fi
if grep -q '@@TORQUED_VM_ERROR' "$log.txt"; then
  grep '@@TORQUED_VM_ERROR' "$log.txt" >&2
fi
sed -n '/@@TORQUED_VM_BEGIN@@/,/@@TORQUED_VM_EXIT=/p' "$log.txt" | sed '1d;$d'
rc=$(sed -n 's/.*@@TORQUED_VM_EXIT=\([0-9]*\)@@.*/\1/p' "$log.txt" | tail -1)
exit "$rc"
