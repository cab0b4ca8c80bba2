#!/usr/bin/env bash
# The README's main job: installs, builds (Release), replays the bundled demo recording (data/demo, 20 s) in
# paced mode through the daemon, which publishes on DDS on loopback; torque-echo (another process, another
# DDS participant) shows the per-cycle torque live in this terminal and records it; at the end torque-eval
# prints the accuracy table against the simulator's truth and writes the plot PNG.
#   tools/scripts/demo.sh [SPEED]     (SPEED: replay speed factor, default 1 = real time)
set -euo pipefail
cd "$(dirname "$0")/../.." && tools/scripts/setup-deps.sh
root=$(pwd)
speed=${1:-1}
# Network hygiene: every DDS participant of the demo stays on loopback.
export CYCLONEDDS_URI="file://${root}/config/cyclonedds-loopback.xml"
echo "== build (Release) ==" >&2
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
# Every tool the README names, so each of its commands works after this one.
cmake --build build -j"$(nproc)" --target torqued torque-echo torque-eval torque-sim torque-decode torque-latency \
  torque-accuracy torque-na-repro torque-canreplay torque-dash >/dev/null
out="${root}/build/demo"
rm -rf "$out" && mkdir -p "$out"
echo "== learned state: starts empty each run ($out/state, removed above), so every run prints the same numbers ==" >&2

# Subscriber first (reliable, volatile: it must be there before the daemon publishes), live table of cycles.
build/tools/torque-echo --topic engine --cycles-only --until-done --record "$out/echo" --duration 300 &
echo_pid=$!
trap 'kill "$echo_pid" "${daemon_pid:-}" 2>/dev/null || true' EXIT
build/service/torqued --config config/demo.yaml --speed "$speed" --exit-when-done --wait-subscribers 1 \
  --state-dir "$out/state" --record "$out/daemon" 2>"$out/torqued.log" &
daemon_pid=$!
wait "$daemon_pid" || { echo "torqued failed, see $out/torqued.log" >&2; tail -20 "$out/torqued.log" >&2; exit 1; }
wait "$echo_pid" || true
trap - EXIT
grep -E "stopped:|latency" "$out/torqued.log" | sed 's/^<[0-9]>//' >&2 || true

echo "== accuracy of the per-cycle brake torque received over DDS (torque-eval) ==" >&2
build/tools/torque-eval --estimate "$out/echo/engine_cycle.csv" --truth data/demo/truth_cycle.csv \
  --column fused_nm=t_brake_mean_nm --column brake_nm=t_brake_mean_nm --column indicated_nm=t_ind_mean_nm \
  --where quality=0 --plot "$out/torque.png" --title "torqued demo: fused brake torque vs truth"
echo "CSV: $out/echo/   daemon log: $out/torqued.log   (torque-eval printed the plot's path above)" >&2
