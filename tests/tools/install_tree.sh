#!/usr/bin/env bash
# ctest tools.install_tree (label integration): the installed tree stands alone.
#   1. `cmake --install` into a throw-away root (DESTDIR, prefix /usr: the package's layout);
#   2. no installed file names the build or the source directory (no compiled-in build-tree path), nor does any
#      tool's --help (the package's man pages are made from it);
#   3. the installed torque-decode --plot runs its installed plot script (PREFIX/share/torqued/plot_decode.py);
#   4. the demo's accuracy figure reproduces from the installed files alone (demo.yaml, recording and truth under
#      /usr/share/torqued/demo): the same torque-eval row as the build tree's README command;
#   5. README.md and docs/ are under /usr/share/doc/torqued.
#   install_tree.sh CMAKE_COMMAND BUILD_DIR SOURCE_DIR
set -uo pipefail
cmake_exe=$1 build=$(cd "$2" && pwd) src=$(cd "$3" && pwd)
tmp=$(mktemp -d /tmp/torqued_install.XXXXXX)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
root=$tmp/root
DESTDIR=$root "$cmake_exe" --install "$build" --prefix /usr >"$tmp/install.log" 2>&1 ||
  fail "cmake --install: $(tail -5 "$tmp/install.log")"
echo "installed $(find "$root" -type f | wc -l) files"

hits=$(grep -rlF -e "$build" -e "$src" "$root" 2>/dev/null)
[[ -z "$hits" ]] || fail "installed files naming the build or source directory ($build, $src):
$hits
$(for f in $hits; do strings "$f" | grep -F -e "$src" | head -3; done)"
echo "no installed file names $src or $build"
# The package's man pages are each tool's --help (help2man): no path of the build may show there either.
for b in "$root"/usr/bin/*; do
  "$b" --help 2>&1 | grep -qF -e "$build" -e "$src" && fail "$(basename "$b") --help shows a build path"
done

share=$root/usr/share/torqued
for f in plot_torque.py plot_latency.py plot_decode.py demo/demo.yaml demo/truth_cycle.csv www/index.html; do
  [[ -e "$share/$f" ]] || { [[ "$f" == www/* && ! -e "$root/usr/bin/torque-dash" ]] || fail "missing /usr/share/torqued/$f"; }
done
[[ -f "$root/usr/share/doc/torqued/README.md" && -f "$root/usr/share/doc/torqued/docs/daemon.md" ]] ||
  fail "README.md / docs not under /usr/share/doc/torqued"

if /usr/bin/python3 -c 'import matplotlib' 2>/dev/null; then
  "$root/usr/bin/torque-decode" --config "$share/demo/demo.yaml" --out-teeth "$tmp/teeth.csv" \
    --plot "$tmp/decode.png" -q >"$tmp/decode.log" 2>&1 || fail "installed torque-decode --plot: $(tail -3 "$tmp/decode.log")"
  head -c 8 "$tmp/decode.png" | od -An -c | grep -q "P   N   G" || fail "torque-decode --plot wrote no PNG"
  echo "installed torque-decode --plot ran /usr/share/torqued/plot_decode.py"
else
  echo "python3-matplotlib missing: torque-decode --plot not run"
fi

row() {  # TORQUED TORQUE_EVAL CONFIG TRUTH -> the fused row of torque-eval after a fast replay
  local out=$tmp/rec_$RANDOM
  "$1" --config "$3" --replay fast --no-dds --fresh-state --record "$out" >/dev/null 2>&1 || return 1
  "$2" --estimate "$out/engine_cycle.csv" --truth "$4" --column fused_nm=t_brake_mean_nm | grep '^fused_nm'
}
want=$(row "$build/service/torqued" "$build/tools/torque-eval" "$src/config/demo.yaml" \
       "$src/data/demo/truth_cycle.csv") || fail "build tree replay failed"
got=$(row "$root/usr/bin/torqued" "$root/usr/bin/torque-eval" "$share/demo/demo.yaml" "$share/demo/truth_cycle.csv") ||
  fail "installed replay failed"
[[ -n "$got" && "$got" == "$want" ]] || fail "installed demo figure differs: '$got' vs build tree '$want'"
echo "installed demo: $got"
echo "PASS: the installed tree stands alone"
