#!/usr/bin/env bash
# ctest metrics_promtool (label integration): `promtool check metrics` (Debian's prometheus package, the
# ecosystem's own lint) accepts a real scrape of torqued's endpoint while it replays the demo (paced, 4x), once
# estimator, engine and status series are all present. Skips (77) when promtool or curl is missing.
#   metrics_promtool.sh TORQUED_EXE SOURCE_DIR
set -uo pipefail
exe=$1 src=$2
for p in promtool curl python3; do
  command -v $p >/dev/null || { echo "SKIP: $p not installed (tools/scripts/setup-deps.sh installs prometheus)"; exit 77; }
done
tmp=$(mktemp -d /tmp/torqued_promtool.XXXXXX)
pid=""
cleanup() { [[ -n "$pid" ]] && kill "$pid" 2>/dev/null; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; echo "--- torqued log"; tail -20 "$tmp/torqued.log"; exit 1; }
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 4.0#" "$src/config/demo.yaml" >"$tmp/torqued.yaml"
printf 'metrics:\n  enabled: true\n  address: "127.0.0.1:%s"\n' "$port" >>"$tmp/torqued.yaml"
"$exe" --config "$tmp/torqued.yaml" --no-dds --fresh-state >"$tmp/torqued.log" 2>&1 &
pid=$!
ok=""
for _ in $(seq 1 40); do  # up to 20 s: a DaemonStatus (1 Hz), a cycle EngineTorque and the fused estimate
  curl -s --max-time 2 "http://127.0.0.1:$port/metrics" >"$tmp/scrape.txt" 2>/dev/null
  if grep -q '^torqued_status_received 1' "$tmp/scrape.txt" && grep -q '^torqued_engine_torque_nm{kind="cycle"' "$tmp/scrape.txt" &&
     grep -q '^torqued_estimator_torque_nm{method="fused"}' "$tmp/scrape.txt"; then ok=1; break; fi
  sleep 0.5
done
[[ -n "$ok" ]] || fail "no complete scrape within 20 s: $(head -c 400 "$tmp/scrape.txt")"
echo "scrape: $(grep -c '^torqued_' "$tmp/scrape.txt") series"
out=$(promtool check metrics <"$tmp/scrape.txt" 2>&1); rc=$?
((rc == 0)) || { echo "$out"; fail "promtool check metrics exit $rc"; }
echo "PASS: promtool check metrics accepts the scrape${out:+ ($out)}"
