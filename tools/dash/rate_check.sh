#!/bin/sh
# The dashboard at the 6000 rpm data rate, 1x real time: torque-sim's steady_4000_high (4 cyl, 60-2) for
# DURATION s, replayed by torqued paced at 1.5x (wall-clock rates of a 6000 rpm engine: 5800 teeth/s, 200
# segments/s) with torque-dash attached (MCAP recording on, the page open in headless Chromium). Prints the
# daemon's drop counters and torque-dash's own counts. Usage: tools/dash/rate_check.sh BUILD_DIR [DURATION_S]
# [DOMAIN]. Needs tools/scripts/setup-deps.sh (chromium, tools/dash/node_modules).
set -eu
build=$1 dur=${2:-30} domain=${3:-26}
src=$(cd "$(dirname "$0")/../.." && pwd)
tmp=$(mktemp -d)
trap 'kill $dash_pid 2>/dev/null; rm -rf "$tmp"' EXIT
export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml" NODE_PATH="$src/tools/dash/node_modules"
"$build/tools/torque-sim" --scenario steady_4000_high --duration "$dur" --out "$tmp/sim" 2>/dev/null
sed -e "s|\.\./data/demo/|$tmp/sim/|" -e "s|dbc: demo.dbc|dbc: $src/config/demo.dbc|" \
  -e "s|domain_id: 0|domain_id: $domain|" "$src/config/demo.yaml" > "$tmp/cfg.yaml"
"$build/tools/torque-dash" --config "$tmp/cfg.yaml" --listen 127.0.0.1:0 --port-file "$tmp/port" --until-done \
  --record-mcap "$tmp/run.mcap" 2> "$tmp/dash.log" &
dash_pid=$!
while [ ! -s "$tmp/port" ]; do sleep 0.1; done
"$build/service/torqued" --config "$tmp/cfg.yaml" --speed 1.5 --exit-when-done --wait-subscribers 1 \
  --state-dir "$tmp/state" > "$tmp/daemon.log" 2>&1 &
daemon_pid=$!
node "$src/tests/integration/dash/page_check.cjs" "http://127.0.0.1:$(cat "$tmp/port")/" "$tmp/rate.png" \
  "$((dur * 2 / 3 - 8))" || echo "page checks failed"
wait $daemon_pid || echo "torqued exited with $?"
wait $dash_pid || true
grep -E "stopped:" "$tmp/daemon.log"
grep -E "^torque-dash: (received|web)" "$tmp/dash.log"
cp "$tmp/rate.png" "${RATE_PNG:-/dev/null}" 2>/dev/null || true
