#!/usr/bin/env bash
# ctest: systemd-analyze verify on systemd/torqued.service (ExecStart pointed at the built binary, since verify
# checks that the executable exists), then the offline security exposure score (printed, must stay "OK" or better).
set -euo pipefail
unit_src=$1 exe=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# man:torqued(1) exists only once the package is installed: verify would fail on it here.
sed -e "s|/usr/bin/torqued|${exe}|g" -e "s|^Documentation=.*|Documentation=man:systemd.service(5)|" \
  "$unit_src" > "$tmp/torqued.service"
systemd-analyze verify "$tmp/torqued.service"
out=$(systemd-analyze security --offline=yes "$tmp/torqued.service" 2>&1 | tail -1)
echo "$out"
grep -qE "OK|SAFE" <<<"$out" || { echo "exposure worse than OK"; exit 1; }
