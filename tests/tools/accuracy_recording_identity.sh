#!/bin/sh
# ctest: torque-accuracy --recording runs the daemon's own angle chain. On the demo recording its per-cycle CSV
# (and every other topic) is byte-identical to `torqued --replay fast --record`; the chain's internal
# chain_cycle.csv has one row per cycle; a bad config exits 2 naming the file.
set -u
acc=$1 torqued=$2 src=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$torqued" --config "$src/config/demo.yaml" --replay fast --no-dds --record "$tmp/daemon" >"$tmp/d.log" 2>&1 ||
  { echo "torqued failed:"; cat "$tmp/d.log"; exit 1; }
"$acc" --recording "$src/config/demo.yaml" --out "$tmp/acc" --truth "$src/data/demo/truth_cycle.csv" --skip-s 1 \
  >"$tmp/a.log" 2>&1 || { echo "torque-accuracy failed:"; cat "$tmp/a.log"; exit 1; }
for f in engine_cycle engine_segment cylinder_torque estimator_torque crank_state daemon_status; do
  cmp "$tmp/daemon/$f.csv" "$tmp/acc/$f.csv" || { echo "$f.csv differs"; exit 1; }
done
rows=$(($(wc -l <"$tmp/acc/chain_cycle.csv") - 1))
cycles=$(($(wc -l <"$tmp/acc/engine_cycle.csv") - 1))
[ "$rows" -eq "$cycles" ] || { echo "chain_cycle.csv: $rows rows for $cycles cycles"; exit 1; }
grep -Eq "^fused_nm = t_brake_mean_nm +cycle" "$tmp/a.log" || { echo "no accuracy table:"; cat "$tmp/a.log"; exit 1; }
printf 'engine:\n  cylinders: many\n' >"$tmp/bad.yaml"
"$acc" --recording "$tmp/bad.yaml" --out "$tmp/x" >"$tmp/b.log" 2>&1; rc=$?
[ $rc -eq 2 ] && grep -q "bad.yaml" "$tmp/b.log" || { echo "bad config: exit $rc"; cat "$tmp/b.log"; exit 1; }
echo "torque-accuracy --recording: byte-identical to torqued fast replay ($cycles cycles)"
