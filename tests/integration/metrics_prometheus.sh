#!/usr/bin/env bash
# ctest metrics_prometheus (label integration): Debian's real Prometheus server, on loopback, scrapes torqued's
# metrics endpoint while it replays the demo (paced, 2x), and its HTTP API must return the expected series:
#   up == 1, torqued_edges_total > 0, the fused estimate, the latency histogram, the example alert rules loaded.
#   metrics_prometheus.sh TORQUED_EXE SOURCE_DIR
# Skips (77) when prometheus/promtool/curl are not installed (setup-deps.sh installs them). Bounded: 90 s.
set -uo pipefail
exe=$1 src=$2
for p in prometheus promtool curl python3; do
  command -v $p >/dev/null || { echo "SKIP: $p not installed (tools/scripts/setup-deps.sh)"; exit 77; }
done
tmp=$(mktemp -d /tmp/torqued_metrics.XXXXXX)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; echo "--- torqued log"; tail -20 "$tmp/torqued.log"; echo "--- prometheus log"; tail -20 "$tmp/prom.log"; exit 1; }
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
mport=$(free_port) pport=$(free_port)

sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 2.0\n  exit_when_done: false#" "$src/config/demo.yaml" >"$tmp/torqued.yaml"
printf 'metrics:\n  enabled: true\n  address: "127.0.0.1:%s"\n' "$mport" >>"$tmp/torqued.yaml"
"$exe" --check-config "$tmp/torqued.yaml" || fail "test configuration refused"
cp "$src/systemd/torqued-alerts.yml" "$tmp/"
promtool check rules "$tmp/torqued-alerts.yml" || fail "promtool refuses the example alert rules"
cat >"$tmp/prometheus.yml" <<EOC
global: {scrape_interval: 1s, evaluation_interval: 1s}
rule_files: [torqued-alerts.yml]
scrape_configs:
  - job_name: torqued
    static_configs: [{targets: ["127.0.0.1:$mport"]}]
EOC
"$exe" --config "$tmp/torqued.yaml" --no-dds --fresh-state >"$tmp/torqued.log" 2>&1 &
pids+=($!)
prometheus --config.file="$tmp/prometheus.yml" --storage.tsdb.path="$tmp/tsdb" \
  --web.listen-address="127.0.0.1:$pport" >"$tmp/prom.log" 2>&1 &
pids+=($!)

query() {  # prints the first value of an instant query, or nothing
  curl -s --max-time 2 "http://127.0.0.1:$pport/api/v1/query" --data-urlencode "query=$1" |
    python3 -c 'import json,sys; r=json.load(sys.stdin)["data"]["result"]; print(r[0]["value"][1] if r else "")' 2>/dev/null
}
deadline=$((SECONDS + 60))
edges=""
while ((SECONDS < deadline)); do
  edges=$(query 'torqued_edges_total{job="torqued"}')
  [[ -n "$edges" && "$edges" != "0" ]] && break
  sleep 1
done
[[ -n "$edges" && "$edges" != "0" ]] || fail "no torqued_edges_total > 0 through Prometheus within 60 s"
echo "torqued_edges_total = $edges"
sleep 3  # a few more scrapes
up=$(query 'up{job="torqued"}')
[[ "$up" == "1" ]] || fail "up{job=torqued} = '$up', expected 1"
fused=$(query 'torqued_estimator_torque_nm{method="fused"}')
[[ -n "$fused" ]] || fail "no torqued_estimator_torque_nm{method=\"fused\"}"
python3 -c "import sys; v=float('$fused'); sys.exit(0 if 0 < v < 1000 else 1)" || fail "fused estimate $fused N m out of (0, 1000)"
n=$(query 'sum(increase(torqued_publish_latency_seconds_count[10s]))')
python3 -c "import sys; sys.exit(0 if float('${n:-0}') > 0 else 1)" || fail "latency histogram did not grow ($n)"
p99=$(query 'histogram_quantile(0.99, rate(torqued_publish_latency_seconds_bucket[10s]))')
echo "fused = $fused N m, publish latency p99 (Prometheus histogram_quantile) = $p99 s"
rules=$(curl -s --max-time 2 "http://127.0.0.1:$pport/api/v1/rules" |
  python3 -c 'import json,sys; print(sum(len(g["rules"]) for g in json.load(sys.stdin)["data"]["groups"]))')
[[ "$rules" == "4" ]] || fail "expected the 4 example alert rules loaded, got '$rules'"
echo "PASS: Prometheus scraped torqued (up=1, edges=$edges, fused=$fused, 4 alert rules loaded)"
