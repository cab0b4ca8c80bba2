#!/bin/sh
# What an MCAP recording costs at 1x: torqued replays the demo paced at 1x (about 20 s) with torque-dash
# recording every topic (--record-mcap). Prints the file's size and rate (MB/s and GB per hour of 1x recording,
# over the log-time span of its messages), torque-dash's CPU time (user + system), and what the MCAP reference
# reader (@mcap/core) reads from it, indexed and streamed. Then the writer alone, offline: torque-mcap-recover
# rewrites the file (zstd, and uncompressed) and reports its time.
# Usage: tools/dash/mcap_cost.sh BUILD_DIR [TORQUE_DASH] [DOMAIN]   (a different torque-dash: e.g. an older build)
# Needs tools/scripts/setup-deps.sh (node, tools/dash/node_modules).
set -eu
build=$1 dash=${2:-$1/tools/torque-dash} domain=${3:-28}
src=$(cd "$(dirname "$0")/../.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml" NODE_PATH="$src/tools/dash/node_modules"
sed -e "s|\.\./data/demo/|$src/data/demo/|" -e "s|dbc: demo.dbc|dbc: $src/config/demo.dbc|" \
  -e "s|domain_id: 0|domain_id: $domain|" "$src/config/demo.yaml" > "$tmp/cfg.yaml"
/usr/bin/time -f "%U %S" -o "$tmp/cpu" "$dash" --config "$tmp/cfg.yaml" --listen 127.0.0.1:0 \
  --port-file "$tmp/port" --until-done --record-mcap "$tmp/run.mcap" 2> "$tmp/dash.log" &
dash_pid=$!
while [ ! -s "$tmp/port" ]; do sleep 0.1; done
"$build/service/torqued" --config "$tmp/cfg.yaml" --speed 1 --exit-when-done --wait-subscribers 1 \
  --state-dir "$tmp/state" > "$tmp/daemon.log" 2>&1
wait $dash_pid
node "$src/tests/integration/dash/mcap_read.cjs" "$tmp/run.mcap" > "$tmp/read.json"
node -e '
  const fs = require("fs");
  const r = require(process.argv[1]), size = fs.statSync(process.argv[2]).size;
  const [u, s] = fs.readFileSync(process.argv[3], "utf8").trim().split(" ").map(Number);
  const st = r.stream, span = Number(BigInt(st.lastLogTime) - BigInt(st.firstLogTime)) / 1e9;
  const mbs = size / span / 1e6;
  console.log(`file ${size} bytes, ${st.messages} messages over ${span.toFixed(2)} s: ${mbs.toFixed(3)} MB/s, ` +
              `${(mbs * 3.6).toFixed(2)} GB per hour at 1x; torque-dash CPU ${(u + s).toFixed(2)} s ` +
              `(user ${u}, system ${s})`);
  const ix = r.indexed;
  console.log(`@mcap/core indexed reader: ${ix.error ? "refused: " + ix.error : ix.messages + " messages in " +
              ix.chunks + " chunks (" + ix.compression + ")"}; streamed reader: ${st.messages} messages` +
              `${st.error ? ", error: " + st.error : ""}`);' "$tmp/read.json" "$tmp/run.mcap" "$tmp/cpu"
sed -n 's/.*; MCAP messages/torque-dash: MCAP messages/p' "$tmp/dash.log"
"$build/tools/torque-mcap-recover" "$tmp/run.mcap" "$tmp/zstd.mcap"
"$build/tools/torque-mcap-recover" --no-compression "$tmp/run.mcap" "$tmp/none.mcap"
echo "rewritten: zstd $(stat -c %s "$tmp/zstd.mcap") bytes, uncompressed chunks $(stat -c %s "$tmp/none.mcap") bytes"
