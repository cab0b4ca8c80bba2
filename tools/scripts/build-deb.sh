#!/usr/bin/env bash
# Builds the Debian package of torqued from this checkout, offline (only installed build dependencies:
# tools/scripts/setup-deps.sh), then runs lintian on it.
#   tools/scripts/build-deb.sh [--no-lintian] [OUT_DIR]     (default OUT_DIR: build/deb)
# --no-lintian: build only (ctest deb_build; ctest deb_lintian then runs tools/scripts/deb-lintian.sh).
# The sources (tracked files plus new, not ignored ones) are copied to OUT_DIR/src and built there with
# dpkg-buildpackage (debhelper, debian/), so the checkout stays clean. Result: OUT_DIR/torqued_<ver>_<arch>.deb,
# OUT_DIR/lintian.txt. Exit 0 when built and lintian reports no error or warning (tags explained in
# debian/torqued.lintian-overrides are accepted), 1 otherwise.
set -euo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
lint=1
if [[ "${1:-}" == "--no-lintian" ]]; then lint=0; shift; fi
out=${1:-$repo/build/deb}
mkdir -p "$out"
out=$(cd "$out" && pwd)
src="$out/src"
rm -rf "$src"
mkdir -p "$src"
(cd "$repo" && git ls-files -z --cached --others --exclude-standard | xargs -0 -I{} sh -c '[ -e "{}" ] && printf "%s\0" "{}"' |
   tar --null -T - -cf - ) | tar -xf - -C "$src"
rm -f "$out"/torqued_*.deb "$out"/torqued-dbgsym_*.deb "$out"/torqued_*.buildinfo "$out"/torqued_*.changes
(cd "$src" && DEB_BUILD_OPTIONS="${DEB_BUILD_OPTIONS:-nocheck parallel=2}" \
   dpkg-buildpackage -b -us -uc >"$out/build.log" 2>&1) || { tail -40 "$out/build.log"; echo "build-deb: dpkg-buildpackage failed (log: $out/build.log)"; exit 1; }
mv "$out"/torqued_*.deb "$out"/torqued_*.buildinfo "$out"/torqued_*.changes "$out"/ 2>/dev/null || true
mv "$out"/src/../torqued*_*.{deb,buildinfo,changes} "$out"/ 2>/dev/null || true
deb=$(ls "$out"/torqued_*.deb | grep -v dbgsym | head -1)
echo "build-deb: $deb"
((lint)) || exit 0
exec "$repo/tools/scripts/deb-lintian.sh" "$deb" "$out/lintian.txt"
