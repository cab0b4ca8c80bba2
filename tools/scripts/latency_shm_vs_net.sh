#!/usr/bin/env bash
# Tooth edge -> subscriber latency over shared memory (iceoryx) and over the network path, same QoS, one after
# the other, each with cyclictest alongside. Both runs use the demo with the QoS iceoryx carries
# (docs/daemon.md, "Shared memory"), so the only difference is the path. As root, RouDi runs in a mount namespace
# of its own (private /tmp and /dev/shm: it neither meets nor disturbs another RouDi); otherwise it must be the
# only RouDi on the machine.
#   tools/scripts/latency_shm_vs_net.sh BUILD_DIR [DURATION_S] [more torque-latency options, e.g. --stress]
set -euo pipefail
build=$(realpath "$1") duration=${2:-15}
shift $(($# < 2 ? $# : 2))
src=$(cd "$(dirname "$0")/../.." && pwd)
roudi=$(command -v iox-roudi) || { echo "iox-roudi not installed (Debian package iceoryx)"; exit 1; }
tmp=$(mktemp -d "$build/latency_shm.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
"$src/tools/scripts/demo-shm-config.sh" "$src" "$tmp/demo_shm.yaml"
latency=("$build/tools/torque-latency" --torqued "$build/service/torqued" --config "$tmp/demo_shm.yaml"
         --duration "$duration" --cyclictest "$@")

echo "=== network path (config/cyclonedds-loopback.xml)"
CYCLONEDDS_URI=file://$src/config/cyclonedds-loopback.xml "${latency[@]}" | tee "$tmp/net.txt"

echo "=== shared memory (config/cyclonedds-shm.xml, RouDi with config/roudi_config.toml)"
cat > "$tmp/shm.sh" <<EOF
set -u
if [[ \$(id -u) == 0 ]]; then mount -t tmpfs tmpfs /tmp && mount -t tmpfs tmpfs /dev/shm; fi
"$roudi" -c "$src/config/roudi_config.toml" > "$tmp/roudi.log" 2>&1 &
roudi_pid=\$!
for i in \$(seq 100); do grep -q "RouDi is ready" "$tmp/roudi.log" && break; sleep 0.1; done
CYCLONEDDS_URI=file://$src/config/cyclonedds-shm.xml $(printf '%q ' "${latency[@]}")
rc=\$?
# ddsperf ends without unregistering from RouDi (it dies on a signal at the end of -D); RouDi's process
# monitor removes such clients after 1.5 s without a heartbeat. Stopping RouDi before that made it abort with
# POSH__ROUDI_PROCESS_SHUTDOWN_FAILED, so wait for the monitor first.
sleep 2
kill -INT \$roudi_pid; wait \$roudi_pid
roudi_rc=\$?
if [[ \$roudi_rc != 0 ]]; then echo "RouDi exited with \$roudi_rc:"; tail -20 "$tmp/roudi.log"; fi
exit \$rc
EOF
if [[ $(id -u) == 0 ]]; then
  unshare --mount --propagation private bash "$tmp/shm.sh" | tee "$tmp/shm.txt"
else
  bash "$tmp/shm.sh" | tee "$tmp/shm.txt"
fi

echo "=== side by side"
grep -h "^summary:" "$tmp/net.txt" "$tmp/shm.txt"
