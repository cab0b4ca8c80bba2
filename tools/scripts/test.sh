#!/usr/bin/env bash
# The README's test command: installs what is missing, builds once (Release), runs every ctest test
# (unit, integration, vm) in parallel, then the unit tests again under ASan+UBSan and the threaded
# tests under TSan. Prints ctest's summary line of each tier. Exit code is non-zero if anything failed.
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$(pwd)
jobs=$(nproc)

tools/scripts/setup-deps.sh
# Network hygiene: every DDS participant started by the tests stays on loopback.
export CYCLONEDDS_URI="file://${root}/config/cyclonedds-loopback.xml"

status=0
summary=()
run_tier() {  # name, build dir, ctest args...
  local name=$1 dir=$2; shift 2
  local log="${dir}/ctest-${name}.log"
  if ctest --test-dir "$dir" -j"$jobs" --output-on-failure --timeout 900 "$@" >"$log" 2>&1; then :; else status=1; fi
  grep -E "tests passed|tests failed" "$log" | tail -1 | sed "s/^/[${name}] /" | tee -a "${root}/build/summary.txt" >/dev/null || true
  if grep -q "tests failed" "$log"; then
    sed -n '/The following tests FAILED/,$p' "$log"
    # What failed, not only which test: each assertion's line and its message (bounded).
    grep -E -A8 ': Failure$' "$log" | head -120 || true
  fi
  summary+=("[${name}] $(grep -E 'tests passed|tests failed' "$log" | tail -1)")
}

echo "== build (Release) =="
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$jobs" 2>&1 | grep -vE '^\[[0-9]+/[0-9]+\]' || true
cmake --build build -j"$jobs" >/dev/null   # fail here if the build failed
: >build/summary.txt
echo "== ctest (all labels) =="
run_tier all build

if [[ "${TORQUED_SKIP_SANITIZERS:-0}" != "1" ]]; then
  echo "== build + ctest (ASan+UBSan, unit tests) =="
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTORQUED_SANITIZE=ON -DTORQUED_BENCHMARKS=OFF >/dev/null
  cmake --build build-asan -j"$jobs" >/dev/null
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    run_tier asan build-asan -L unit

  echo "== build + ctest (TSan, threaded tests: label tsan) =="
  cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DTORQUED_TSAN=ON -DTORQUED_BENCHMARKS=OFF >/dev/null
  cmake --build build-tsan -j"$jobs" --target test_spsc_ring test_runtime_alloc test_socketcan test_latest_value \
    test_learned_handoff test_sink_thread test_read_ahead_merger test_fast_replay >/dev/null
  TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1 run_tier tsan build-tsan -L tsan
fi

# ---- fuzzing: a short bounded run of every libFuzzer target (clang build in build-fuzz) ----
if [[ "${TORQUED_SKIP_FUZZ:-0}" != "1" ]]; then
  echo "== fuzz (5 s per target; fuzz_config: 100 000 inputs) =="
  if tools/scripts/fuzz.sh "${TORQUED_FUZZ_SECONDS:-5}" build-fuzz | tee build/fuzz.txt; then :; else status=1; fi
  summary+=("[fuzz] $(tail -1 build/fuzz.txt)")
fi
# ---- end fuzzing ----

# ---- habits: clang-format on the whole tree, clang-tidy on the files the last commit changed ----
echo "== lint =="
if tools/scripts/lint.sh build | tee build/lint.txt; then :; else status=1; fi
summary+=("[lint] $(grep -c '^lint: .*clean' build/lint.txt)/2 checks clean")

echo "== summary =="
printf '%s\n' "${summary[@]}"
exit $status
