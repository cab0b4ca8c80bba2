#!/bin/sh
# tests/tools/torque_echo_gaps.sh TORQUED TORQUE_ECHO SOURCE_DIR WORK_DIR: torque-echo tells the truth about
# lost samples (the finding: a subscriber stalled for 10 s lost 907 samples and exited 0 without a word). The
# daemon replays the demo at 4x; torque-echo (keep-last 1) is stopped for 1 s mid-run: it must report the
# missing samples per topic at exit and, with --fail-on-gaps, exit 5. DDS on loopback (CYCLONEDDS_URI from ctest),
# a domain and prefix of its own.
set -u
TORQUED=$1
ECHO=$2
SRC=$3
WORK=$4/torque_echo_gaps
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
sed -e "s#\.\./data/demo/#$SRC/data/demo/#" -e "s#dbc: demo.dbc#dbc: $SRC/config/demo.dbc#" \
    -e "s#topic_prefix: torque#topic_prefix: echo_gaps#" -e "s#domain_id: 0#domain_id: 41#" \
    "$SRC/config/demo.yaml" > "$WORK/demo.yaml"
"$ECHO" --config "$WORK/demo.yaml" --topic all --format none --until-done --history 1 --fail-on-gaps \
  > /dev/null 2> "$WORK/echo.err" &
echo_pid=$!
sleep 1
timeout 60 "$TORQUED" --config "$WORK/demo.yaml" --replay paced --speed 4 --fresh-state --state-dir "$WORK/state" \
  --exit-when-done > "$WORK/daemon.log" 2>&1 &
daemon_pid=$!
sleep 2
kill -STOP "$echo_pid"
sleep 1
kill -CONT "$echo_pid"
wait "$daemon_pid"
timeout 30 sh -c "while kill -0 $echo_pid 2>/dev/null; do sleep 0.2; done"
wait "$echo_pid"
rc=$?
cat "$WORK/echo.err"
if [ "$rc" -ne 5 ]; then echo "FAIL: torque-echo exit $rc, want 5 (--fail-on-gaps after a 1 s stall)"; exit 1; fi
if ! grep -q "samples missing (sequence gaps)" "$WORK/echo.err"; then echo "FAIL: no gap report"; exit 1; fi
echo "ok: the stall's losses were reported"
