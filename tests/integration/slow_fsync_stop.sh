#!/usr/bin/env bash
# ctest slow_fsync_stop (label integration): with every fsync slowed to 8 s (LD_PRELOAD shim), a daemon that
# records and keeps a learned state stops within 2 s of SIGTERM (systemd's stop timeout is 5 s), and its log
# says what was not flushed (the recording files whose fsync did not return, the state save left unfinished).
#   slow_fsync_stop.sh TORQUED_EXE SHIM_SO SOURCE_DIR       (about 10 s)
set -uo pipefail
exe=$1 shim=$2 src=$3
tmp=$(mktemp -d /tmp/torqued_slowfsync.XXXXXX)
dpid=
cleanup() { [[ -n $dpid ]] && kill -9 "$dpid" 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; tail -15 "$tmp/torqued.log"; exit 1; }
sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 1.0\n  exit_when_done: false#" "$src/config/demo.yaml" >"$tmp/paced.yaml"
mkdir -p "$tmp/state"
# A first run at normal speed fills the state directory (learned state, start-up table cache), so that the
# slow run reads them instead of writing them at start.
"$exe" --config "$tmp/paced.yaml" --replay fast --no-dds --state-dir "$tmp/state" >"$tmp/first.log" 2>&1 ||
  fail "first (fast) run"
SLOW_FSYNC_S=8 LD_PRELOAD="$shim" "$exe" --config "$tmp/paced.yaml" --no-dds \
  --state-dir "$tmp/state" --record "$tmp/rec" >"$tmp/torqued.log" 2>&1 &
dpid=$!
# Run long enough for the recording files to exist and the first cycles to be learned.
for _ in $(seq 1 80); do [[ -s $tmp/rec/engine_cycle.csv ]] && break; sleep 0.25; done
[[ -s $tmp/rec/engine_cycle.csv ]] || fail "no recording after 20 s"
sleep 3
kill -0 "$dpid" 2>/dev/null || fail "the daemon exited before SIGTERM"
t0=$(date +%s.%N)
kill -TERM "$dpid"
wait "$dpid"
rc=$?
t1=$(date +%s.%N)
dpid=
stop_s=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
printf 'stop after SIGTERM with 8 s fsyncs: %.2f s, exit %d\n' "$stop_s" "$rc"
awk -v s="$stop_s" 'BEGIN { exit !(s < 2.0) }' || fail "stop took $stop_s s (limit 2 s)"
grep -q "recording: fsync of .* not finished within the stop budget" "$tmp/torqued.log" ||
  fail "the log does not say which recording files were not flushed"
grep "not finished within the stop budget\|did not finish within the stop budget" "$tmp/torqued.log"
echo "PASS: stopped in $stop_s s under 8 s fsyncs, the log names what was not flushed"
