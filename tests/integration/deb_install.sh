#!/usr/bin/env bash
# ctest deb_install (label integration): the Debian package (tools/scripts/build-deb.sh) installed for real with
# dpkg into a throw-away copy-on-write root (overlayfs over / + chroot; the host is not touched), then the
# service's own command lines taken from the installed unit, run as its system user:
#   install (sysusers user, unit enabled, conffiles) -> ExecStartPre (--check-config) passes -> ExecStart
#   reaches READY=1 (sd_notify on our socket) -> publishes on DDS (torque-echo) and serves metrics -> learned
#   state saved -> kill -9 -> restarted, loads the learned state -> SIGTERM stops cleanly (exit 0, < 5 s)
#   -> the conffile is edited -> upgrade over itself keeps the edit -> purge removes files and conffiles.
# systemd is not PID 1 here, so StateDirectory= is created the way systemd would (owner torqued, 0750) and
# the restart after kill -9 is done by this script (the unit has Restart=on-failure).
#   deb_install.sh DEB_DIR     (the torqued_*.deb in it; build/deb by tools/scripts/build-deb.sh)
# Skips (77) without root/overlayfs or when no package was built (build it with tools/scripts/build-deb.sh).
set -uo pipefail
deb=$(ls "$1"/torqued_*_"$(dpkg --print-architecture)".deb 2>/dev/null | head -1)
[[ -n "$deb" ]] || { echo "SKIP: no torqued_*.deb in $1 (tools/scripts/build-deb.sh)"; exit 77; }
[[ $(id -u) -eq 0 ]] || { echo "SKIP: needs root (dpkg into an overlay root)"; exit 77; }
tmp=$(mktemp -d /tmp/torqued_deb.XXXXXX)
m=$tmp/root
mkdir -p "$tmp"/{upper,work} "$m"
mount -t overlay overlay -o "lowerdir=/,upperdir=$tmp/upper,workdir=$tmp/work" "$m" 2>/dev/null ||
  { rm -rf "$tmp"; echo "SKIP: cannot mount overlayfs here"; exit 77; }
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  for d in tmp run proc dev; do umount -l "$m/$d" 2>/dev/null; done
  umount -l "$m" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
mount --bind /dev "$m/dev" && mount -t proc proc "$m/proc" && mount -t tmpfs tmpfs "$m/run" &&
  mount -t tmpfs tmpfs "$m/tmp" || { echo "FAIL: mounts in the overlay root"; exit 1; }
fail() { echo "FAIL: $*"; [[ -f "$m/tmp/torqued.log" ]] && tail -15 "$m/tmp/torqued.log"; exit 1; }
inside() { chroot "$m" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C "$@"; }
cp "$deb" "$m/tmp/torqued.deb"
inside dpkg --purge torqued >/dev/null 2>&1  # a copy already installed on the host does not count

# --- install ------------------------------------------------------------------------------------------------
timeout 120 chroot "$m" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin dpkg -i /tmp/torqued.deb </dev/null ||
  fail "dpkg -i"
inside getent passwd torqued | grep -q nologin || fail "system user torqued not created by sysusers"
[[ -L "$m/etc/systemd/system/multi-user.target.wants/torqued.service" ]] || fail "unit not enabled"
grep -qx /etc/torqued/torqued.yaml <(inside dpkg-query -W -f='${Conffiles}\n' torqued | awk '{print $1}') ||
  fail "/etc/torqued/torqued.yaml is not a conffile"
# torque-dash (the README names it) with its page; the packaged configuration loops the demo.
[[ -x "$m/usr/bin/torque-dash" && -f "$m/usr/share/torqued/www/index.html" ]] || fail "torque-dash or its page missing"
inside torque-dash --help >/dev/null || fail "torque-dash --help"
grep -qE '^  loop: true' "$m/etc/torqued/torqued.yaml" || fail "packaged torqued.yaml does not set replay.loop"
unit=$m/lib/systemd/system/torqued.service
pre=$(sed -n 's/^ExecStartPre=//p' "$unit") start=$(sed -n 's/^ExecStart=//p' "$unit")
env_uri=$(sed -n 's/^Environment=CYCLONEDDS_URI=//p' "$unit")
[[ -n "$pre" && -n "$start" && -n "$env_uri" ]] || fail "unit lacks ExecStartPre/ExecStart/CYCLONEDDS_URI"
inside $pre || fail "ExecStartPre ($pre) refuses the packaged configuration"
install -d -o "$(inside id -u torqued)" -g "$(inside id -g torqued)" -m 0750 "$m/var/lib/torqued"

# --- start as the service would, READY, publishes, metrics ---------------------------------------------------
start_service() {  # $1: log file inside the root
  rm -f "$m/run/notify"  # a fresh socket for each start (as systemd gives each start its own)
  python3 - "$m/run/notify" "$tmp/notify.txt" <<'PY' &
import socket, sys
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM); s.bind(sys.argv[1])
import os; os.chmod(sys.argv[1], 0o777)
with open(sys.argv[2], "a", buffering=1) as f:
    while True:
        f.write(s.recv(4096).decode() + "\n")
PY
  pids+=($!)
  sleep 0.5
  chroot --userspec=torqued:torqued "$m" env -i PATH=/usr/bin:/bin NOTIFY_SOCKET=/run/notify \
    CYCLONEDDS_URI="$env_uri" $start >"$m$1" 2>&1 &
  svc=$!
  pids+=($svc)
  for _ in $(seq 100); do grep -q '^READY=1' "$tmp/notify.txt" 2>/dev/null && return 0; sleep 0.2; done
  fail "no READY=1 within 20 s"
}
: >"$tmp/notify.txt"
start_service /tmp/torqued.log
echo "READY=1 received"
grep -q 'replay.loop: the recording restarts' "$m/tmp/torqued.log" || fail "the service does not loop the demo"
n=$(inside env CYCLONEDDS_URI="$env_uri" torque-echo --topic engine --format json --count 5 --duration 20 -q | wc -l)
((n >= 5)) || fail "torque-echo received $n EngineTorque samples, expected 5"
echo "published: torque-echo received $n EngineTorque samples"
for _ in $(seq 20); do  # DaemonStatus (and so the counters) comes once a second
  curl -s --max-time 3 http://127.0.0.1:9464/metrics >"$tmp/metrics.txt" 2>/dev/null
  grep -qE '^torqued_edges_total [1-9]' "$tmp/metrics.txt" && break
  sleep 0.5
done
grep -qE '^torqued_edges_total [1-9]' "$tmp/metrics.txt" ||
  fail "metrics endpoint 127.0.0.1:9464 does not show edges: $(grep -E 'edges|status_received' "$tmp/metrics.txt")"
echo "metrics: $(grep -E '^torqued_(edges_total|health) ' "$tmp/metrics.txt" | tr '\n' ' ')"
for _ in $(seq 60); do [[ -s "$m/var/lib/torqued/learned_state.txt" ]] && break; sleep 0.5; done
[[ -s "$m/var/lib/torqued/learned_state.txt" ]] || fail "no learned state saved within 30 s"

# --- kill -9, restart with the learned state -----------------------------------------------------------------
kill -9 "$svc"; wait "$svc" 2>/dev/null
: >"$tmp/notify.txt"
start_service /tmp/torqued2.log
grep -q 'learned state loaded from /var/lib/torqued/learned_state.txt' "$m/tmp/torqued2.log" ||
  fail "restart after kill -9 did not load the learned state: $(grep -i 'learned' "$m/tmp/torqued2.log")"
echo "restarted after kill -9 with the learned state"

# --- stop ---------------------------------------------------------------------------------------------------
t0=$SECONDS
kill -TERM "$svc"
wait "$svc"
rc=$?
((rc == 0 && SECONDS - t0 <= 5)) || fail "SIGTERM: exit $rc after $((SECONDS - t0)) s (expected 0 within 5 s)"
echo "stopped cleanly"

# --- upgrade over itself keeping an edited conffile ---------------------------------------------------------
sed -i 's/^  speed: 1.0/  speed: 3.0   # edited by the user/' "$m/etc/torqued/torqued.yaml"
grep -q 'edited by the user' "$m/etc/torqued/torqued.yaml" || fail "could not edit the conffile"
timeout 120 chroot "$m" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin dpkg -i /tmp/torqued.deb </dev/null ||
  fail "upgrade over itself"
grep -q 'edited by the user' "$m/etc/torqued/torqued.yaml" || fail "upgrade lost the edit of torqued.yaml"
inside $pre || fail "edited configuration refused after upgrade"
echo "upgrade kept the edited conffile"

# --- purge --------------------------------------------------------------------------------------------------
timeout 120 chroot "$m" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin dpkg --purge torqued </dev/null || fail "purge"
for f in /usr/bin/torqued /usr/bin/torque-dash /usr/share/torqued/www /etc/torqued/torqued.yaml /etc/torqued/cyclonedds.xml /lib/systemd/system/torqued.service \
         /etc/systemd/system/multi-user.target.wants/torqued.service; do
  [[ ! -e "$m$f" && ! -L "$m$f" ]] || fail "$f left after purge"
done
# Documented (docs/daemon.md): the learned state and the system user stay after purge.
[[ -s "$m/var/lib/torqued/learned_state.txt" ]] || fail "purge removed the learned state (documented as kept)"
inside getent passwd torqued >/dev/null || fail "purge removed the user (documented as kept)"
echo "PASS: install (torque-dash too), READY, replay loop on, publish, kill -9 restart with learned state, stop, upgrade keeping the conffile, purge"
