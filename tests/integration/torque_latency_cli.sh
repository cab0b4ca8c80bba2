#!/bin/sh
# ctest: torque-latency runs the daemon (paced demo replay, 4x) for 3 s, receives CrankState and EngineTorque in
# its own process, prints the split table with a consistent split (edge -> dds_write and dds_write -> received
# both below edge -> received at p50), the daemon's final counters with no ring drops, and writes the PNG.
# Timing figures are not asserted (shared machine). Args: torque-latency torqued source-dir.
set -u
lat=$1 torqued=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml"
sed -e "s|\.\./data/demo/|$src/data/demo/|" -e "s|dbc: demo.dbc|dbc: $src/config/demo.dbc|" \
  "$src/config/demo.yaml" > "$tmp/demo.yaml"
out=$("$lat" --torqued "$torqued" --config "$tmp/demo.yaml" --duration 3 --speed 4 --plot "$tmp/lat.png" 2>&1); rc=$?
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
echo "$out" | grep -Eq "daemon: stopped: .* drops edge/can/out/source 0/0/0/0" || { echo "ring drops or no counters: $out"; exit 1; }
head -c 8 "$tmp/lat.png" | od -An -c | grep -q "P   N   G" || { echo "no PNG written: $out"; exit 1; }
echo "torque-latency CLI OK: n=$n p50 total $total us (daemon $daemon, DDS $dds)"
