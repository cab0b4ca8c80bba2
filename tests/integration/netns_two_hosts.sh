#!/usr/bin/env bash
# ctest: "two hosts" = two network namespaces joined by a veth pair with link-local addresses (169.254.x.y,
# nothing routable, nothing outside the namespaces). torqued runs in one, torque-echo in the other; the
# per-cycle torque must cross. Needs root (CAP_NET_ADMIN); skipped (exit 77) otherwise.
set -euo pipefail
torqued=$1 echo_exe=$2 src=$3
[[ $(id -u) == 0 ]] || { echo "SKIP: needs root for ip netns"; exit 77; }
id=$$
a=tqa_$id b=tqb_$id va=tqva$id vb=tqvb$id
tmp=$(mktemp -d)
cleanup() { ip netns del "$a" 2>/dev/null || true; ip netns del "$b" 2>/dev/null || true; rm -rf "$tmp"; }
trap cleanup EXIT
# shellcheck source=netns_pair.sh
. "$(dirname "$0")/netns_pair.sh"
netns_pair "$a" "$b" "$va" "$vb" 169.254.77
cyclone() {  # interface, peer
  cat <<XML
<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any">
  <General><Interfaces><NetworkInterface name="$1"/></Interfaces><AllowMulticast>false</AllowMulticast></General>
  <Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address="$2"/></Peers></Discovery>
</Domain></CycloneDDS>
XML
}
cyclone "$va" 169.254.77.2 > "$tmp/a.xml"
cyclone "$vb" 169.254.77.1 > "$tmp/b.xml"
ip netns exec "$b" env CYCLONEDDS_URI="file://$tmp/b.xml" \
  "$echo_exe" --topic engine --cycles-only --until-done --format none --record "$tmp/echo" --duration 60 \
  > "$tmp/echo.log" 2>&1 &
echo_pid=$!
sleep 0.5
ip netns exec "$a" env CYCLONEDDS_URI="file://$tmp/a.xml" \
  "$torqued" --config "$src/config/demo.yaml" --speed 4 --exit-when-done --wait-subscribers 1 \
  --state-dir "$tmp/state" > "$tmp/daemon.log" 2>&1 || { cat "$tmp/daemon.log"; exit 1; }
wait "$echo_pid" || true
rows=$(($(wc -l < "$tmp/echo/engine_cycle.csv" 2>/dev/null || echo 1) - 1))
echo "cycles received across the veth pair: $rows"
cat "$tmp/echo.log"
grep -q "subscriber(s) matched" "$tmp/daemon.log" || { echo "FAILED: no subscriber matched across namespaces"; cat "$tmp/daemon.log"; exit 1; }
(( rows > 300 )) || { echo "FAILED: expected > 300 cycles"; exit 1; }
