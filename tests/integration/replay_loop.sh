#!/usr/bin/env bash
# ctest replay_loop: replay.loop keeps a paced replay of the demo going past its end, as the packaged
# service does. The demo (20 s) at 20x for 6 s with replay.loop: true must
#   - announce the loop and never report the end of the recording,
#   - publish (here: record) engine cycles past the second seam (recording time > 45 s), with valid estimates
#     (quality 0) in the third loop, i.e. the decoder resynced after each seam,
#   - keep the engine-cycle times increasing.
#   replay_loop.sh TORQUED SOURCE_DIR
set -uo pipefail
torqued=$1 src=$2
tmp=$(mktemp -d /tmp/torqued_loop.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; tail -20 "$tmp/log"; exit 1; }
sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 20.0\n  loop: true#" "$src/config/demo.yaml" >"$tmp/loop.yaml"
grep -q "loop: true" "$tmp/loop.yaml" || fail "could not set replay.loop in a copy of config/demo.yaml"
timeout -s TERM 6 "$torqued" --config "$tmp/loop.yaml" --no-dds --fresh-state --record "$tmp/rec" >"$tmp/log" 2>&1
grep -q "replay.loop: the recording restarts every 20.000 s" "$tmp/log" || fail "no replay.loop line in the log"
! grep -q "end of the recording reached" "$tmp/log" || fail "the looped replay reported the end of the recording"
python3 - "$tmp/rec/engine_cycle.csv" <<'PY' || fail "engine cycles (above)"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
t = [int(r["t_ns"]) for r in rows]
assert all(b > a for a, b in zip(t, t[1:])), "engine-cycle times not increasing"
third = [r for r in rows if int(r["t_ns"]) > 45_000_000_000]
good = [r for r in third if r["quality"] == "0"]
print(f"{len(rows)} cycles up to t = {t[-1] * 1e-9:.1f} s; past 45 s: {len(third)}, of which quality 0: {len(good)}")
assert len(good) >= 100, "too few valid cycles in the third loop"
PY
echo "PASS: replay.loop"
