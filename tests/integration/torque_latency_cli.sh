#!/bin/sh
# ctest: torque-latency runs the daemon (paced demo replay, 4x) for 3 s, receives CrankState and EngineTorque in
# its own process, prints the split table with a consistent split (edge -> dds_write and dds_write -> received
# both below edge -> received at p50), the daemon's final counters with no ring drops, and writes the PNG.
# It takes the DDS domain, topic prefix and engine_id from the config (here 7, lat, 3: samples arrive only if it
# does), prints the floors and the ratio to them when cyclictest is installed, the tail's stages from the daemon's
# stamps (all samples joined on seq), and leaves no temporary files.
# Timing figures are not asserted (shared machine). Args: torque-latency torqued source-dir.
set -u
lat=$1 torqued=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml"
sed -e "s|\.\./data/demo/|$src/data/demo/|" -e "s|dbc: demo.dbc|dbc: $src/config/demo.dbc|" \
  -e "s|domain_id: 0|domain_id: 7|" -e "s|topic_prefix: torque|topic_prefix: lat|" -e "s|engine_id: 1|engine_id: 3|" \
  "$src/config/demo.yaml" > "$tmp/demo.yaml"
grep -q "domain_id: 7" "$tmp/demo.yaml" && grep -q "engine_id: 3" "$tmp/demo.yaml" || { echo "demo.yaml changed"; exit 1; }
floors=""
command -v cyclictest >/dev/null && floors=--cyclictest
out=$("$lat" --torqued "$torqued" --config "$tmp/demo.yaml" --duration 3 --speed 4 --plot "$tmp/lat.png" $floors 2>&1); rc=$?
[ $rc -eq 0 ] || { echo "exit $rc: $out"; exit 1; }
row() { echo "$out" | grep -F "$1" | head -1; }
crank=$(row "tooth edge -> CrankState (subscriber)")
n=$(echo "$crank" | awk '{print $(NF-4)}')
total=$(echo "$crank" | awk '{print $(NF-3)}')
daemon=$(echo "$out" | grep -F "edge -> dds_write (in the daemon)" | head -1 | awk '{print $(NF-3)}')
dds=$(echo "$out" | grep -F "dds_write -> received (DDS)" | head -1 | awk '{print $(NF-3)}')
[ -n "$n" ] && [ "$n" -gt 200 ] || { echo "too few CrankState samples ($n): $out"; exit 1; }
awk -v t="$total" -v a="$daemon" -v b="$dds" 'BEGIN { exit !(t > 0 && a > 0 && b > 0 && a < t && b < t) }' ||
  { echo "inconsistent split: total $total, daemon $daemon, DDS $dds: $out"; exit 1; }
echo "$out" | grep -Eq "daemon: stopped: .* drops edge/can/out/source 0/0/0/" || { echo "ring drops or no counters: $out"; exit 1; }
echo "$out" | grep -q "DDS domain 7, topics lat/\*, engine_id 3" || { echo "not the config's DDS settings: $out"; exit 1; }
# The tail's stages: every CrankState joined with the daemon's stamps (--stage-trace), one stage named owner.
echo "$out" | grep -Eq "the tail's stages \(CrankState, [0-9]+ samples >= p99.9 [0-9.]+ us; ([0-9]+) of \1 joined" &&
  echo "$out" | grep -q "the tail's stages: owned by \"" || { echo "no tail stages: $out"; exit 1; }
if [ -n "$floors" ]; then
  echo "$out" | grep -Eq "vs floor: edge -> dds_write p50 [0-9.]+ us = cyclictest p50 [-+][0-9.]+ us" ||
    { echo "no floor comparison: $out"; exit 1; }
  echo "$out" | grep -Eq "p99.9 [0-9.]+ us, cyclictest p99.9 [0-9.]+ us: [0-9.]+x" || { echo "no p99.9 ratio: $out"; exit 1; }
fi
if echo "$out" | grep -q "logs kept in"; then echo "temporary directory left behind: $out"; exit 1; fi
head -c 8 "$tmp/lat.png" | od -An -c | grep -q "P   N   G" || { echo "no PNG written: $out"; exit 1; }
echo "torque-latency CLI OK: n=$n p50 total $total us (daemon $daemon, DDS $dds)"
