#!/usr/bin/env bash
# Runs inside the VM of `run_in_vm.sh --systemd` (systemd is PID 1; the root is a copy-on-write overlay of the
# host's, so the package can be installed for real): the Debian package's service under systemd, one check after
# the other, in the order of a package's life: install, ready, publish, metrics, restart, stop, upgrade, purge.
# Each check leaves <check>.log and <check>.rc in $TORQUED_VM_OUT (the writable 9p share); output also echoed.
#   vm_sd_checks.sh DEB
# A check that needs an earlier one (all of them need install) fails with the reason when that one failed.
# shellcheck disable=SC2317  # the check_* functions are called indirectly (run_check)
set -u
deb=$1
out=${TORQUED_VM_OUT:-/tmp/vm-out}
unit=torqued.service
conf=/etc/torqued/torqued.yaml
state=/var/lib/torqued/learned_state.txt
dds_uri=file:///etc/torqued/cyclonedds.xml
edit_marker="# edited in the VM test"
fails=0

# dpkg runs at SCHED_FIFO 90: under TCG the service's real-time threads (SCHED_FIFO up to 85, as packaged) keep
# both emulated CPUs busy and would starve a normal dpkg for minutes (its maintainer scripts inherit the priority;
# the service itself is started by systemd, which does not).
dpkg_rt() { chrt -f 90 dpkg "$@" </dev/null; }
prop() { systemctl show -P "$1" "$unit"; }
show() { systemctl show "$unit" -p "$(IFS=,; echo "$*")"; }
# Waits up to $1 s for the unit to be active with a main PID other than $2 (default: any).
wait_active() {
  local i pid
  for ((i = 0; i < $1 * 2; i++)); do
    pid=$(prop MainPID)
    [[ $(prop ActiveState) == active && $pid != 0 && $pid != "${2:-}" ]] && return 0
    sleep 0.5
  done
  echo "not active within $1 s:"; show ActiveState SubState Result MainPID NRestarts StatusText
  journalctl -u "$unit" -o short-monotonic --no-pager | tail -20
  return 1
}
# Journal lines (message only) of the unit's current run (its invocation).
run_journal() { journalctl -o cat --no-pager "_SYSTEMD_INVOCATION_ID=$(prop InvocationID)"; }
# Fetches the metrics on 127.0.0.1:$1 until torqued_edges_total is positive (up to $2 s); prints the torqued_ lines.
metrics_with_edges() {
  local i body
  for ((i = 0; i < $2; i++)); do
    body=$(curl -s --max-time 3 "http://127.0.0.1:$1/metrics")
    if grep -qE '^torqued_edges_total [1-9]' <<<"$body"; then grep '^torqued_' <<<"$body"; return 0; fi
    sleep 1
  done
  echo "127.0.0.1:$1/metrics: no positive torqued_edges_total within $2 s (got: $(grep -c . <<<"$body") lines)"
  return 1
}

check_install() {
  # Under TCG (software emulation, many times slower than the host) the unit's WatchdogSec=2s and the default
  # start time-out are too short; this VM-only drop-in, written before the package exists, gives them room.
  mkdir -p /etc/systemd/system/torqued.service.d
  printf '[Service]\nWatchdogSec=30s\nTimeoutStartSec=180s\n' >/etc/systemd/system/torqued.service.d/vm-tcg.conf
  echo "network interfaces (qemu -nic none): $(ip -br link | awk '{print $1}' | tr '\n' ' ')"
  # The host root is a container image: its /usr/sbin/policy-rc.d forbids starting services (exit 101), which a
  # Debian system booted with systemd does not have; without it postinst starts the service as on a real machine.
  # man-db's trigger (rebuilds the whole man index, minutes under TCG) is not what is tested: off.
  rm -f /usr/sbin/policy-rc.d /var/lib/man-db/auto-update
  local t0=$SECONDS
  dpkg_rt -i "$deb" || { echo "FAIL: dpkg -i $deb"; return 1; }
  echo "dpkg -i took $((SECONDS - t0)) s (postinst: sysusers, enable, start)"
  getent passwd torqued | grep -q nologin || { echo "FAIL: system user torqued missing"; return 1; }
  [[ $(systemctl is-enabled "$unit") == enabled ]] || { echo "FAIL: unit not enabled"; return 1; }
  [[ -L /etc/systemd/system/multi-user.target.wants/$unit ]] || { echo "FAIL: no multi-user.target.wants link"; return 1; }
  dpkg-query -W -f='${Conffiles}\n' torqued | grep -q "^ $conf " || { echo "FAIL: $conf is not a conffile"; return 1; }
  prop DropInPaths | grep -q vm-tcg.conf || { echo "FAIL: the VM drop-in is not applied"; return 1; }
  # DDS of the service stays on this machine: lo only, no multicast.
  if ! grep -q '<NetworkInterface name="lo"/>' /etc/torqued/cyclonedds.xml ||
     ! grep -q '<AllowMulticast>false</AllowMulticast>' /etc/torqued/cyclonedds.xml; then
    echo "FAIL: /etc/torqued/cyclonedds.xml is not loopback-only"; return 1
  fi
  [[ $(prop Environment) == *"CYCLONEDDS_URI=$dds_uri"* ]] || { echo "FAIL: unit does not set CYCLONEDDS_URI"; return 1; }
  echo "PASS: installed; user torqued, unit enabled, conffile, loopback-only DDS configuration"
}

check_ready() {
  [[ -n $(prop FragmentPath) ]] || { echo "FAIL: no unit (install failed)"; return 1; }
  # postinst started it (deb-systemd-invoke start waits for READY=1 of a Type=notify unit).
  wait_active 120 || { echo "FAIL: $unit not active"; return 1; }
  local i pid
  for ((i = 0; i < 20; i++)); do [[ -n $(prop StatusText) ]] && break; sleep 1; done
  show ActiveState SubState Type Result NRestarts StatusText MainPID WatchdogUSec User ExecMainStartTimestamp
  [[ $(prop Type) == notify && $(prop SubState) == running ]] || { echo "FAIL: not a running Type=notify unit"; return 1; }
  [[ -n $(prop StatusText) ]] || { echo "FAIL: no STATUS= from the daemon"; return 1; }
  pid=$(prop MainPID)
  [[ $(ps -o user= -p "$pid") == torqued ]] || { echo "FAIL: main process does not run as torqued"; return 1; }
  # The unit's grants (CAP_SYS_NICE, LimitRTPRIO, the system call filter) let the daemon make its threads SCHED_FIFO.
  local fifo
  fifo=$(ps -L -o cls=,rtprio=,comm= -p "$pid" | awk '$1 == "FF"' | sort -u)
  echo "SCHED_FIFO threads (class, priority, name):"; echo "$fifo"
  [[ -n $fifo ]] || { echo "FAIL: no SCHED_FIFO thread (realtime.* not granted under systemd)"; return 1; }
  # ExecStartPre (torqued --check-config) of this run: its verdict is in the run's journal.
  run_journal | grep -m1 "^$conf: OK" || { echo "FAIL: no '$conf: OK' from ExecStartPre"; systemctl show -p ExecStartPre "$unit"; return 1; }
  [[ $(stat -c '%U %a' /var/lib/torqued) == "torqued 750" ]] || { echo "FAIL: StateDirectory: $(stat -c '%U %a' /var/lib/torqued)"; return 1; }
  run_journal | grep -m1 '^.*running (paced replay)' || { echo "FAIL: no 'running (paced replay)' in the journal"; return 1; }
  echo "PASS: active (running) after READY=1, STATUS=\"$(prop StatusText)\", user torqued, SCHED_FIFO threads, ExecStartPre passed, /var/lib/torqued created"
}

check_publish() {
  local samples n
  samples=$(CYCLONEDDS_URI=$dds_uri timeout 150 torque-echo --topic engine --format json --count 5 --duration 120 -q)
  n=$(grep -c . <<<"$samples")
  head -1 <<<"$samples"
  ((n >= 5)) || { echo "FAIL: torque-echo received $n EngineTorque samples, expected 5"; return 1; }
  echo "PASS: torque-echo (the package's, loopback DDS) received $n EngineTorque samples from the service"
}

check_metrics() {
  # The packaged torqued.yaml enables metrics on 127.0.0.1:9464. The edit moves them to :9465, and that edited
  # conffile is what check_upgrade expects dpkg to keep.
  metrics_with_edges 9464 60 | grep -E '^torqued_(edges_total|health) ' || { echo "FAIL: packaged endpoint"; return 1; }
  sed -i "s/^  address: \"127.0.0.1:9464\"/  address: \"127.0.0.1:9465\"   $edit_marker/" "$conf"
  grep -q "$edit_marker" "$conf" || { echo "FAIL: could not edit metrics.address in $conf"; return 1; }
  torqued --check-config "$conf" || { echo "FAIL: edited configuration refused"; return 1; }
  local pid
  pid=$(prop MainPID)
  systemctl restart "$unit" || { echo "FAIL: systemctl restart after the edit"; return 1; }
  wait_active 120 "$pid" || { echo "FAIL: not active after the restart"; return 1; }
  metrics_with_edges 9465 60 | grep -E '^torqued_(edges_total|health|learned_state_age_seconds) ' ||
    { echo "FAIL: edited endpoint 127.0.0.1:9465"; return 1; }
  ss -ltn | grep -q '127.0.0.1:9465 ' || { echo "FAIL: not listening on 127.0.0.1:9465 only"; return 1; }
  ! curl -s --max-time 3 -o /dev/null http://127.0.0.1:9464/metrics || { echo "FAIL: 9464 still answers"; return 1; }
  echo "PASS: metrics on 127.0.0.1:9464 as packaged, on 127.0.0.1:9465 after editing the conffile and a restart"
}

check_restart() {
  local i pid n0 n1
  for ((i = 0; i < 60; i++)); do [[ -s $state ]] && break; sleep 1; done
  [[ -s $state ]] || { echo "FAIL: no learned state in $state within 60 s"; return 1; }
  pid=$(prop MainPID) n0=$(prop NRestarts)
  echo "kill -9 $pid (NRestarts $n0)"
  kill -9 "$pid"
  wait_active 120 "$pid" || { echo "FAIL: not restarted after kill -9"; return 1; }
  n1=$(prop NRestarts)
  show MainPID NRestarts StatusText
  ((n1 == n0 + 1)) || { echo "FAIL: NRestarts $n0 -> $n1, expected +1"; return 1; }
  journalctl -u "$unit" -o cat --no-pager | grep -m1 'code=killed, status=9/KILL' || { echo "FAIL: systemd did not log the KILL"; return 1; }
  run_journal | grep -m1 "learned state loaded from $state" ||
    { echo "FAIL: the restarted daemon did not load $state:"; run_journal | grep -i learned; return 1; }
  echo "PASS: kill -9 -> restarted by systemd (Restart=on-failure, NRestarts $n0 -> $n1) with the learned state"
}

check_stop() {
  [[ $(prop ActiveState) == active ]] || { echo "FAIL: not running before the stop"; return 1; }
  local id t0 t1 ms limit
  id=$(prop InvocationID)
  touch -d '@1' "$state" 2>/dev/null  # so that the save while stopping shows in the mtime
  t0=$(date +%s%N)
  systemctl stop "$unit"
  t1=$(date +%s%N)
  # What TimeoutStopSec bounds: from leaving "active" (SIGTERM sent) to "inactive", as systemd timed it (the
  # wall time of the systemctl command adds its own start-up, slow under TCG).
  ms=$((($(prop InactiveEnterTimestampMonotonic) - $(prop ActiveExitTimestampMonotonic)) / 1000))
  limit=$(($(prop TimeoutStopUSec | sed 's/s$//') * 1000))
  show ActiveState Result ExecMainCode ExecMainStatus TimeoutStopUSec
  echo "stop: $ms ms from SIGTERM to inactive (systemctl stop: $(((t1 - t0) / 1000000)) ms; TimeoutStopSec $((limit / 1000)) s)"
  [[ $(prop ActiveState) == inactive && $(prop Result) == success && $(prop ExecMainStatus) == 0 ]] ||
    { echo "FAIL: did not exit cleanly"; return 1; }
  ((ms < limit)) || { echo "FAIL: stop took longer than TimeoutStopSec"; return 1; }
  journalctl -o cat --no-pager "_SYSTEMD_INVOCATION_ID=$id" | grep -m1 -E '^.*(SIGTERM: draining|stopped: )' || { echo "FAIL: no drain/stopped in the journal"; return 1; }
  journalctl -o cat --no-pager "_SYSTEMD_INVOCATION_ID=$id" | grep -E 'not saved|did not finish' && { echo "FAIL: state save or drain problem"; return 1; }
  (($(stat -c %Y "$state") > 1)) || { echo "FAIL: learned state not saved at exit"; return 1; }
  pgrep -u torqued >/dev/null && { echo "FAIL: processes of torqued left"; return 1; }
  echo "PASS: SIGTERM -> exit 0 in $ms ms (< TimeoutStopSec), learned state file rewritten while stopping, no save error"
}

check_upgrade() {
  grep -q "$edit_marker" "$conf" || { echo "FAIL: no edited conffile to keep (the metrics check failed)"; return 1; }
  systemctl start "$unit" || { echo "FAIL: systemctl start before the upgrade"; return 1; }
  wait_active 120 || { echo "FAIL: not active before the upgrade"; return 1; }
  local pid t0=$SECONDS
  pid=$(prop MainPID)
  dpkg_rt -i "$deb" || { echo "FAIL: dpkg -i over itself"; return 1; }
  echo "upgrade took $((SECONDS - t0)) s"
  grep "$edit_marker" "$conf" || { echo "FAIL: the upgrade lost the edit"; return 1; }
  ls /etc/torqued/*.dpkg-* 2>/dev/null && { echo "FAIL: dpkg left conffile copies"; return 1; }
  wait_active 120 "$pid" || { echo "FAIL: not running (restarted by postinst) after the upgrade"; return 1; }
  metrics_with_edges 9465 60 | grep '^torqued_edges_total' || { echo "FAIL: the edited address is not in effect"; return 1; }
  [[ $(dpkg-query -W -f='${Status}' torqued) == "install ok installed" ]] || { echo "FAIL: package state"; return 1; }
  echo "PASS: upgrade over itself kept the edited torqued.yaml; the service was restarted ($pid -> $(prop MainPID)) and uses it"
}

check_purge() {
  dpkg-query -W torqued >/dev/null 2>&1 || { echo "FAIL: not installed"; return 1; }
  dpkg_rt --purge torqued || { echo "FAIL: dpkg --purge"; return 1; }
  rm -rf /etc/systemd/system/torqued.service.d && systemctl daemon-reload  # this test's own drop-in
  show LoadState ActiveState
  [[ $(prop LoadState) == not-found ]] || { echo "FAIL: unit still loadable"; return 1; }
  pgrep -u torqued >/dev/null && { echo "FAIL: processes of torqued left"; return 1; }
  local f
  for f in /usr/bin/torqued /lib/systemd/system/$unit /etc/systemd/system/multi-user.target.wants/$unit /etc/torqued; do
    [[ ! -e $f && ! -L $f ]] || { echo "FAIL: $f left after purge"; return 1; }
  done
  # Documented (docs/daemon.md): the system user and /var/lib/torqued (learned state) stay after purge.
  getent passwd torqued >/dev/null || { echo "FAIL: user removed (documented as kept)"; return 1; }
  [[ -s $state ]] || { echo "FAIL: learned state removed (documented as kept)"; return 1; }
  echo "PASS: purge stopped the service and removed unit, enablement, binaries and /etc/torqued; user and state kept (documented)"
}

run_check() {
  local name=$1 t0=$SECONDS rc
  echo "=== vm_sd check: $name"
  "check_$name" >"$out/$name.log" 2>&1
  rc=$?
  echo "(check took $((SECONDS - t0)) s in the VM)" >>"$out/$name.log"
  cat "$out/$name.log"
  echo "$rc" >"$out/$name.rc"
  echo "=== vm_sd check: $name -> exit $rc"
  ((rc == 0)) || fails=$((fails + 1))
}

echo "systemd $(systemctl --version | head -1 | cut -d' ' -f2) is PID 1: $(cat /proc/1/comm); system: $(systemctl is-system-running)"
for c in install ready publish metrics restart stop upgrade purge; do run_check "$c"; done
journalctl -u "$unit" -o short-monotonic --no-pager >"$out/journal-torqued.txt" 2>&1
journalctl -b -p warning -o short-monotonic --no-pager >"$out/journal-warnings.txt" 2>&1
echo "vm_sd checks failed: $fails"
exit "$fails"
