#!/bin/sh
# ctest: torque-eval on synthetic CSVs (estimate = truth + 3 N m) prints bias/RMS 3.000 and writes a PNG.
set -u
eval_bin=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
awk 'BEGIN { print "cycle,t_start_s,t_end_s,t_brake_mean_nm";
  for (i = 0; i < 20; i++) printf "%d,%.3f,%.3f,%d\n", i, i * 0.05, (i + 1) * 0.05, 100 + i }' > "$tmp/truth_cycle.csv"
awk 'BEGIN { print "t_ns,window_start_t_ns,fused_nm";
  for (i = 0; i < 20; i++) printf "%d,%d,%d\n", (i + 1) * 50000000, i * 50000000, 103 + i }' > "$tmp/est.csv"
out=$("$eval_bin" --estimate "$tmp/est.csv" --truth "$tmp/truth_cycle.csv" --column fused_nm=t_brake_mean_nm \
      --plot "$tmp/out.png" 2>&1); rc=$?
[ $rc -eq 0 ] || { echo "exit $rc: $out"; exit 1; }
echo "$out" | grep -Eq "fused_nm = t_brake_mean_nm +cycle +20 +3\.000 +3\.000 +3\.000 +0\.000" || { echo "unexpected table: $out"; exit 1; }
head -c 8 "$tmp/out.png" | od -An -c | grep -q "P   N   G" || { echo "no PNG written: $out"; exit 1; }
out=$("$eval_bin" --estimate "$tmp/est.csv" --truth "$tmp/truth_cycle.csv" --column fused_nm=nope 2>&1); rc=$?
[ $rc -eq 1 ] && echo "$out" | grep -q "truth column 'nope'" || { echo "bad column: exit $rc: $out"; exit 1; }
echo "torque-eval CLI OK"
