#!/usr/bin/env bash
# lintian on the torqued package (all tags, pedantic and informational ones too); the output is also kept in LOG.
#   tools/scripts/deb-lintian.sh DEB [LOG]
# Exit 0 when lintian reports no error, no warning and no spelling tag (spelling-error-in-*: info level, but a
# user reads them as sloppiness; tags overridden in debian/torqued.lintian-overrides, each with its reason there,
# are accepted and listed as O:); 1 otherwise; 77 (ctest skip) without lintian.
set -uo pipefail
deb=$1
log=${2:-}
command -v lintian >/dev/null || { echo "SKIP: lintian not installed (tools/scripts/setup-deps.sh installs it)"; exit 77; }
[[ -f "$deb" ]] || { echo "FAIL: no package '$deb' (tools/scripts/build-deb.sh builds it)"; exit 1; }
tmp=$(mktemp)
trap 'rm -f "$tmp"' EXIT
lintian --info --display-info --pedantic --show-overrides "$deb" >"$tmp" 2>&1
lrc=$?
cat "$tmp"
[[ -z "$log" ]] || cp "$tmp" "$log"
if grep -qE '^[EW]: ' "$tmp" || ((lrc > 1)); then
  echo "deb-lintian: lintian errors/warnings above (lintian exit $lrc)"; exit 1
fi
if grep -qE '^[IP]: .*spelling-error' "$tmp"; then
  echo "deb-lintian: spelling tags above (a message split by the compiler can form one: reword it)"; exit 1
fi
echo "deb-lintian: no error, warning or spelling tag; $(grep -cE '^[IPX]: ' "$tmp") info/pedantic/experimental tags, $(grep -c '^O: ' "$tmp") overridden"
