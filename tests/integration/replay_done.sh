#!/usr/bin/env bash
# ctest replay_done (label integration): the end of a replay is a state, not a fault.
#   1. a paced replay of files that does not loop exits 0 by itself once the recording is consumed
#      (replay.exit_when_done, default true);
#   2. with replay.exit_when_done: false the daemon keeps running in a steady done state: every DaemonStatus from
#      the end on carries REPLAY_DONE, health 0 (the ended input degrades nothing; overruns or drops of the
#      machine still do), and torque-echo reading
#      the engine topic says once that the replay is done and prints no "deadline missed" afterwards.
#   replay_done.sh TORQUED_EXE TORQUE_ECHO_EXE SOURCE_DIR       (demo at 20x: about 10 s)
set -uo pipefail
exe=$1 echo_exe=$2 src=$3
tmp=$(mktemp -d /tmp/torqued_done.XXXXXX)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; for f in "$tmp"/*.log; do echo "--- $f"; tail -8 "$f"; done; exit 1; }
sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 20.0#" "$src/config/demo.yaml" >"$tmp/paced.yaml"

timeout 30 "$exe" --config "$tmp/paced.yaml" --no-dds --fresh-state >"$tmp/default.log" 2>&1; rc=$?
((rc == 0)) && grep -q "end of the recording reached; stopping" "$tmp/default.log" ||
  fail "default paced replay: exit $rc, expected 0 once the recording is consumed"
echo "default: exit 0 at the end of the recording"

sed -e "s#speed: 20.0#speed: 20.0\n  exit_when_done: false#" "$tmp/paced.yaml" >"$tmp/keep.yaml"
"$echo_exe" --config "$tmp/keep.yaml" --topic engine --format none >"$tmp/echo.out" 2>"$tmp/echo.log" &
pids+=($!)
"$exe" --config "$tmp/keep.yaml" --fresh-state --wait-subscribers 1 --record "$tmp/rec" >"$tmp/torqued.log" 2>&1 &
dpid=$!
pids+=($dpid)
for _ in $(seq 1 60); do grep -q "end of the recording reached" "$tmp/torqued.log" && break; sleep 0.5; done
grep -q "end of the recording reached; still running" "$tmp/torqued.log" || fail "no end of the recording within 30 s"
sleep 4  # 4 status periods and 4 engine deadlines (1 s) after the end
kill -0 "$dpid" 2>/dev/null || fail "torqued with replay.exit_when_done: false exited at the end"
kill -TERM "$dpid"; wait "$dpid"; rc=$?
((rc == 0)) || fail "SIGTERM after the end: exit $rc"
# daemon_status.csv: t_ns,...,validity,health,flags,...: from the first REPLAY_DONE row on, every row has it and
# health 0.
python3 - "$tmp/rec/daemon_status.csv" <<'PY' || fail "status after the end"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
first = next((i for i, r in enumerate(rows) if int(r["flags"]) & 64), None)
assert first is not None, "no REPLAY_DONE status"
after = rows[first:]
assert len(after) >= 3, f"only {len(after)} status rows after the end"
# Degraded only by a condition of its own (RT refused 1, mlock 2, drops 32, overruns 256 on a loaded machine,
# record error 512), never by the ended input (edge/CAN timeout, no sync); never failed.
own = 1 | 2 | 32 | 256 | 512
bad = [(r["seq"], r["flags"], r["health"]) for r in after
       if not int(r["flags"]) & 64 or r["health"] == "2" or (r["health"] != "0" and not int(r["flags"]) & own)]
assert not bad, f"rows after the end without REPLAY_DONE or with a health the end explains (seq, flags, health): {bad}"
print(f"status: {len(after)} rows after the end, all REPLAY_DONE, health 0 but for conditions of their own")
PY
grep -q "the daemon reported the end of its replay" "$tmp/echo.log" || fail "torque-echo did not report the end"
sed -n '/the daemon reported the end of its replay/,$p' "$tmp/echo.log" | grep -q "deadline missed" &&
  fail "torque-echo printed 'deadline missed' after the end of the replay"
echo "PASS: replay done is a state (exit 0 by default; steady REPLAY_DONE, health 0; no deadline noise)"
