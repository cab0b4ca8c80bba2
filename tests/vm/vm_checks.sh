#!/bin/sh
# Runs inside the VM (chrooted into the host root, vcan0 up): every vcan check, one after the other.
# Results go to $TORQUED_VM_OUT (writable 9p share): <check>.log and <check>.rc; the output is also echoed.
#   vm_checks.sh BUILD_DIR INPUT_DIR
build=$1
in=$2
out=${TORQUED_VM_OUT:-/tmp/vm-out}
fails=0
run_check() {
  name=$1; shift
  echo "=== vm check: $name"
  "$@" >"$out/$name.log" 2>&1
  rc=$?
  cat "$out/$name.log"
  echo "$rc" >"$out/$name.rc"
  echo "=== vm check: $name -> exit $rc"
  [ "$rc" -eq 0 ] || [ "$rc" -eq 77 ] || fails=$((fails + 1))
}
ip link set vcan0 mtu 72 2>/dev/null  # CAN FD
run_check socketcan_unit "$build/tests/io/test_socketcan"
dbc=""
[ -f "$in/demo.dbc" ] && dbc="--dbc $in/demo.dbc"
run_check frames "$build/tests/vm/vm_can_check" frames --log "$in/can.log" $dbc --iface vcan0
run_check encoder "$build/tests/vm/vm_can_check" encoder --edges "$in/edges.csv" --log "$in/encoder.log" --tick-ns 1 --iface vcan0
# candump captures what the project itself sends (torque-canreplay send, 2x speed). Under software emulation on a
# busy host candump can fall behind: a 4 MiB socket buffer (-r) so it drops nothing, and a generous time-out.
n=$(grep -c '^(' "$in/can.log")
run_check send sh -c "timeout 120 candump -r 4194304 -L -n $n vcan0 >/tmp/captured.log & cpid=\$!; sleep 0.5; \
  $build/tools/torque-canreplay send --fd --speed 2 --iface vcan0 $in/can.log && wait \$cpid && \
  $build/tests/vm/vm_can_check compare --a $in/can.log --b /tmp/captured.log"
run_check downup "$build/tests/vm/vm_can_check" downup --iface vcan0
run_check gpio sh "$(dirname "$0")/vm_gpio.sh" "$build"   # 77 = skipped: gpio-sim.ko not built for this kernel
echo "vm checks failed: $fails"
exit "$fails"
