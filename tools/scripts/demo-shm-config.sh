#!/usr/bin/env bash
# Writes the demo configuration with the QoS of docs/daemon.md "Shared memory" (keep-last 16 per writer, no
# deadline, CrankState reliable; lock_on_fault keeps iceoryx's 66 MB management segment out of the locked RSS),
# with absolute paths to the repository's demo data. Used by tests/integration/netns_two_hosts_shm.sh and
# tools/scripts/latency_shm_vs_net.sh.
#   demo-shm-config.sh REPO_DIR OUT_YAML
set -euo pipefail
src=$1
out=$2
sed -e "s|\.\./data/demo/|$src/data/demo/|g" -e "s|dbc: demo.dbc|dbc: $src/config/demo.dbc|" \
    -e "s|^  lock_memory: true|  lock_memory: true\n  lock_on_fault: true|" \
    -e "s|^  domain_id: 0|  domain_id: 0\n  qos:\n\
    engine_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n\
    estimator_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n\
    cylinder_torque: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n\
    crank_state: {reliability: reliable, history_depth: 16, deadline_ms: 0}\n\
    status: {reliability: reliable, history_depth: 4, deadline_ms: 0}|" \
    "$src/config/demo.yaml" > "$out"
