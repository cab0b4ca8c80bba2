#!/bin/sh
# tests/service/startup_refusals.sh TORQUED SOURCE_DIR WORK_DIR: every start-up refusal of the daemon known
# here is caught by `torqued --check-config` (the service's ExecStartPre relies on it). For each hostile
# variant of config/demo.yaml: the daemon refuses to run (exit != 0) AND --check-config exits 1. Before, the
# check passed a DDS topic prefix the daemon then died on (dds_create_topic), a replay.speed of 1e-300
# (undefined conversion, paced replay flat out) and an edge CSV without the configured crank column.
# DDS on loopback only (CYCLONEDDS_URI set by ctest). DBC contents are checked by the DBC parser's own tests.
set -u
TORQUED=$1
SRC=$2
WORK=$3/startup_refusals
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
base() {  # the demo configuration with absolute paths
  sed -e "s#\.\./data/demo/#$SRC/data/demo/#" -e "s#dbc: demo.dbc#dbc: $SRC/config/demo.dbc#" "$SRC/config/demo.yaml"
}
fail=0
n=0
check() {  # name, then a sed program applied to the demo configuration
  name=$1
  n=$((n + 1))
  base | sed -e "$2" > "$WORK/$name.yaml"
  timeout 60 "$TORQUED" --config "$WORK/$name.yaml" --replay fast --fresh-state --state-dir "$WORK/state_$name" \
    --record "$WORK/rec_$name" > "$WORK/$name.run.log" 2>&1
  run_rc=$?
  timeout 60 "$TORQUED" --check-config "$WORK/$name.yaml" > "$WORK/$name.check.log" 2>&1
  check_rc=$?
  if [ "$run_rc" -eq 0 ] || [ "$check_rc" -ne 1 ]; then
    echo "FAIL $name: daemon exit $run_rc (want != 0), --check-config exit $check_rc (want 1)"
    sed 's/^/  check: /' "$WORK/$name.check.log" | head -5
    sed 's/^/  run:   /' "$WORK/$name.run.log" | tail -3
    fail=1
  else
    echo "ok   $name: daemon exit $run_rc, --check-config: $(head -1 "$WORK/$name.check.log")"
  fi
}
check topic_prefix     's#^  topic_prefix: torque#  topic_prefix: "a/b c*?"#'
check replay_speed     's#^  speed: 1.0#  speed: 1e-300#'
check crank_column     's#^  crank_channel: crank#  crank_channel: nosuch#'
check cam_column       's#^  cam_channel: cam#  cam_channel: nosuch#'
check edges_missing    "s#$SRC/data/demo/edges.csv#$WORK/nosuch.csv#"
check can_missing      "s#$SRC/data/demo/can.log#$WORK/nosuch.log#"
check dbc_missing      "s#dbc: $SRC/config/demo.dbc#dbc: $WORK/nosuch.dbc#"
check metrics_address  's#^dds:#metrics: {enabled: true, address: "no such address"}\ndds:#'
check rod_too_short    's#^  rod_m: 0.1450#  rod_m: 0.01#'
check firing_order     's#^  firing_order: \[1, 3, 4, 2\]#  firing_order: [1, 3, 3, 2]#'
# The unchanged demo configuration passes both (the cases above refuse for their own reason only).
base > "$WORK/demo.yaml"
if ! "$TORQUED" --check-config "$WORK/demo.yaml" > /dev/null 2>&1; then
  echo "FAIL: the demo configuration does not pass --check-config"
  fail=1
fi
echo "$n start-up refusals checked"
exit $fail
