#!/usr/bin/env bash
# Runs every libFuzzer target of fuzz/ for SECONDS each (default 5; fuzz_config: 100 000 inputs, see below) from its seed corpus (fuzz/corpus/<name>,
# read-only: new inputs go to a scratch directory) and prints the executions of each and in total.
# Usage: tools/scripts/fuzz.sh [--seconds N] [--build-dir DIR] [SECONDS] [BUILD_DIR]
#   (DIR default build-fuzz, configured here with clang). Long run, one core, low priority:
#   nice -n 19 tools/scripts/fuzz.sh --seconds 200    (five targets: about 17 min)
# A crash leaves its reproducer in BUILD_DIR/fuzz-artifacts/ and makes the exit status non-zero.
set -euo pipefail
cd "$(dirname "$0")/../.."
secs=5
dir=build-fuzz
positional=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --seconds) secs=${2:?--seconds needs a number}; shift 2 ;;
    --seconds=*) secs=${1#*=}; shift ;;
    --build-dir) dir=${2:?--build-dir needs a directory}; shift 2 ;;
    --build-dir=*) dir=${1#*=}; shift ;;
    -h|--help) sed -n '2,8p' "$0"; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) positional+=("$1"); shift ;;
  esac
done
[[ ${#positional[@]} -ge 1 ]] && secs=${positional[0]}
[[ ${#positional[@]} -ge 2 ]] && dir=${positional[1]}
[[ $secs =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: --seconds must be a positive integer (got '$secs')" >&2; exit 2; }
if [[ ! -f "$dir/CMakeCache.txt" ]]; then
  CC=clang CXX=clang++ cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTORQUED_FUZZ=ON \
    -DTORQUED_BENCHMARKS=OFF >/dev/null
fi
cmake --build "$dir" -j"$(nproc)" --target fuzz_all >/dev/null
mkdir -p "$dir/fuzz-artifacts"
total=0
status=0
for t in edges:edge_csv candump:candump dbc:dbc config:config state:state; do
  name=${t%%:*} corpus=fuzz/corpus/${t#*:}
  scratch=$(mktemp -d)
  log="$dir/fuzz-${name}.log"
  # The configuration loader is the slow target (a YAML parse per input): it runs a fixed number of inputs
  # (TORQUED_FUZZ_CONFIG_RUNS, default 100 000) within at most 60 x SECONDS instead of SECONDS.
  limit=(-max_total_time="$secs")
  [[ $name == config ]] && limit=(-runs="${TORQUED_FUZZ_CONFIG_RUNS:-100000}" -max_total_time=$((secs * 60)))
  if ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$dir/fuzz/fuzz_${name}" "${limit[@]}" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$dir/fuzz-artifacts/${name}-" "$scratch" "$corpus" >"$log" 2>&1; then :; else
    status=1
    echo "fuzz_${name}: FAILED (see $log)"
    grep -E "ERROR|runtime error" "$log" | head -5 || true
  fi
  rm -rf "$scratch"
  runs=$(grep -oE "Done [0-9]+ runs" "$log" | grep -oE "[0-9]+" || echo 0)
  total=$((total + runs))
  took=$(grep -oE "Done [0-9]+ runs in [0-9]+ second" "$log" | grep -oE "in [0-9]+" | grep -oE "[0-9]+" || echo "$secs")
  echo "fuzz_${name}: ${runs} executions in ${took} s"
done
echo "fuzz: ${total} executions in total"
exit $status
