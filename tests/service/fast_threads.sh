#!/bin/sh
# tests/service/fast_threads.sh TORQUED SOURCE_DIR WORK_DIR: replay.fast_threads through the daemon. The demo
# recording replayed fast with fast_threads 1, 3 and auto records byte-identical CSV files (daemon_status.csv
# holds every DaemonStatus count at every period), each run's start line names the threads it used and why,
# and auto on one CPU (taskset, when present) resolves to one thread.
set -u
TORQUED=$1
SRC=$2
WORK=$3/fast_threads
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
fail() { echo "FAIL: $*"; exit 1; }
# The demo configuration with absolute input paths (its relative ones resolve against its own directory).
config() {
  sed -e "s#\.\./data#$SRC/data#" -e "s#dbc: demo.dbc#dbc: $SRC/config/demo.dbc#" \
      -e "s#^  mode: paced#  mode: fast\n  fast_threads: $1#" "$SRC/config/demo.yaml" > "$WORK/$1.yaml"
  grep -q "fast_threads: $1" "$WORK/$1.yaml" || fail "could not set replay.fast_threads in $WORK/$1.yaml"
}
run() {  # $1 setting, $2 tag, then a command prefix (taskset ...)
  set_=$1 tag=$2; shift 2
  "$@" "$TORQUED" --config "$WORK/$set_.yaml" --no-dds --fresh-state --state-dir "$WORK/state_$tag" \
    --record "$WORK/rec_$tag" > "$WORK/$tag.log" 2>&1 || fail "the replay ($tag) failed: $WORK/$tag.log"
}
for n in 1 3 auto; do config "$n"; run "$n" "$n"; done
grep -q "fast replay threads: one .*(replay.fast_threads 1)" "$WORK/1.log" || fail "1: no one-thread line"
grep -q "fast replay threads: reader, chain, recording writer (replay.fast_threads 3)" "$WORK/3.log" ||
  fail "3: no three-thread line"
grep -q "fast replay threads: .*(replay.fast_threads auto, [0-9]* CPUs\? usable)" "$WORK/auto.log" ||
  fail "auto: no line with the CPU count"
files=0
for f in "$WORK"/rec_1/*.csv; do
  name=$(basename "$f")
  for tag in 3 auto; do
    cmp -s "$f" "$WORK/rec_$tag/$name" || fail "$name differs between fast_threads 1 and $tag"
  done
  files=$((files + 1))
done
[ "$files" -ge 3 ] && [ -f "$WORK/rec_1/daemon_status.csv" ] || fail "only $files recorded files"
if command -v taskset > /dev/null 2>&1; then
  run auto one_cpu taskset -c 0
  grep -q "fast replay threads: one .*(replay.fast_threads auto, 1 CPU usable)" "$WORK/one_cpu.log" ||
    fail "auto on one CPU did not resolve to one thread: $(grep 'fast replay threads' "$WORK/one_cpu.log")"
  cmp -s "$WORK/rec_1/daemon_status.csv" "$WORK/rec_one_cpu/daemon_status.csv" ||
    fail "daemon_status.csv differs on one CPU"
fi
echo "ok: fast_threads 1, 3 and auto recorded $files identical files"
