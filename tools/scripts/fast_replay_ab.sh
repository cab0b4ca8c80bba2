#!/bin/bash
# Fast-replay loop wall time of two torqued builds, alternating runs (A B A B ...) so both see the same load.
# The figure is torqued's own loop time (first record to the recording written), taken from the "NNNx real
# time" it prints (4 significant digits; the seconds are printed with 3 decimals only).
#   tools/scripts/fast_replay_ab.sh CONFIG N BIN_A BIN_B [--record] [--config-b CONFIG_B]
# e.g. torque-sim -s steady_3000_mid --duration 20 -o /tmp/s3000, a config pointing at it (docs/daemon.md),
#   tools/scripts/fast_replay_ab.sh /tmp/s3000.yaml 30 /tmp/torqued.before build/service/torqued --record
# --config-b: B runs with CONFIG_B (the same recording, e.g. another replay.fast_threads), A with CONFIG.
# Prints best, first quartile and median loop time per build. Use the best of many runs on a shared VM.
# Each build keeps its own table cache (XDG_CACHE_HOME), warmed by one untimed run before the loop: with one shared
# cache, two builds whose table keys differ would rebuild each other's tables on every run. (A config that sets a
# table or state directory overrides XDG_CACHE_HOME: leave both unset in the config given here.)
set -euo pipefail
if [ $# -lt 4 ]; then sed -n '2,13p' "$0"; exit 2; fi
cfg=$1 n=$2 a=$3 b=$4 rec="" cfg_b=$1
shift 4
while [ $# -gt 0 ]; do
  case $1 in
    --record) rec=--record; shift ;;
    --config-b) cfg_b=${2:?--config-b needs a file}; shift 2 ;;
    *) echo "fast_replay_ab.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
mkdir -p "$out/cache_a" "$out/cache_b"
run() {  # $1 binary, $2 tag: prints x real time
  local c=$cfg
  if [ "$2" = b ]; then c=$cfg_b; fi
  local args=(--config "$c" --replay fast --no-dds)
  if [ "$rec" = --record ]; then rm -rf "$out/rec_$2"; args+=(--record "$out/rec_$2"); fi
  XDG_CACHE_HOME="$out/cache_$2" "$1" "${args[@]}" 2>&1 |
    sed -n 's/.*recording in [0-9.]* s (\([0-9]*\)x real time).*/\1/p'
}
dur=$(XDG_CACHE_HOME="$out/cache_a" "$a" --config "$cfg" --replay fast --no-dds 2>&1 |
  sed -n 's/.*fast replay: \([0-9.]*\) s of recording.*/\1/p')
XDG_CACHE_HOME="$out/cache_b" "$b" --config "$cfg_b" --replay fast --no-dds > /dev/null 2>&1
for _ in $(seq "$n"); do
  echo "A $(run "$a" a)" >> "$out/x"
  echo "B $(run "$b" b)" >> "$out/x"
done
for t in A B; do
  grep "^$t [0-9]" "$out/x" | awk -v d="$dur" '{print 1000 * d / $2}' | sort -n |
    awk -v t="$t" -v d="$dur" '{a[NR] = $1} END {printf "%s: loop best %.1f ms (%.0fx real time), q25 %.1f ms, median %.1f ms, n = %d\n", t, a[1], 1000 * d / a[1], a[int(NR / 4) + 1], a[int((NR + 1) / 2)], NR}'
done
