#!/bin/bash
# Fast-replay loop wall time of two torqued builds, alternating runs (A B A B ...) so both see the same load.
# The figure is torqued's own loop time (first record to the recording written), taken from the "NNNx real
# time" it prints (4 significant digits; the seconds are printed with 3 decimals only).
#   tools/scripts/fast_replay_ab.sh CONFIG N BIN_A BIN_B [--record]
# e.g. torque-sim -s steady_3000_mid --duration 20 -o /tmp/s3000, a config pointing at it (docs/daemon.md),
#   tools/scripts/fast_replay_ab.sh /tmp/s3000.yaml 30 /tmp/torqued.before build/service/torqued --record
# Prints best, first quartile and median loop time per build. Use the best of many runs on a shared VM.
set -euo pipefail
if [ $# -lt 4 ]; then sed -n '2,9p' "$0"; exit 2; fi
cfg=$1 n=$2 a=$3 b=$4 rec=${5:-}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {  # $1 binary, $2 tag: prints x real time
  local args=(--config "$cfg" --replay fast --no-dds)
  if [ "$rec" = --record ]; then rm -rf "$out/rec_$2"; args+=(--record "$out/rec_$2"); fi
  "$1" "${args[@]}" 2>&1 | sed -n 's/.*recording in [0-9.]* s (\([0-9]*\)x real time).*/\1/p'
}
dur=$("$a" --config "$cfg" --replay fast --no-dds 2>&1 | sed -n 's/.*fast replay: \([0-9.]*\) s of recording.*/\1/p')
for _ in $(seq "$n"); do
  echo "A $(run "$a" a)" >> "$out/x"
  echo "B $(run "$b" b)" >> "$out/x"
done
for t in A B; do
  grep "^$t [0-9]" "$out/x" | awk -v d="$dur" '{print 1000 * d / $2}' | sort -n |
    awk -v t="$t" -v d="$dur" '{a[NR] = $1} END {printf "%s: loop best %.1f ms (%.0fx real time), q25 %.1f ms, median %.1f ms, n = %d\n", t, a[1], 1000 * d / a[1], a[int(NR / 4) + 1], a[int((NR + 1) / 2)], NR}'
done
