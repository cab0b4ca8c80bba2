#!/usr/bin/env bash
# ctest tools.cli_usage: what a new user meets on the command line.
#   - every binary's --help lists its exit statuses; a command-line error exits 2 (not CLI11's 105...);
#   - torqued without arguments says what to give and exits 2; --config of a missing file exits 2;
#   - torque-accuracy: an unknown scenario exits 2 and lists the known ones;
#   - torque-eval: an unknown column lists the columns that exist (exit 1); the table calls max |error| max|err|;
#   - the plot: one panel per quantity, identical estimates merged, a PNG written;
#   - torque-dash like the others (exit 2 on a bad option, exit statuses and defaults in --help);
#   - paced replay reports its end and exits with replay.exit_when_done;
#   - torque-latency: a daemon that cannot start or exits early is named with its log, exit 1.
#   cli_usage.sh BUILD_DIR SOURCE_DIR
set -uo pipefail
build=$1 src=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
for b in service/torqued tools/torque-sim tools/torque-echo tools/torque-eval tools/torque-decode \
         tools/torque-canreplay tools/torque-latency tools/torque-accuracy tools/torque-dash tools/torque-mcap-recover; do
  [[ -x "$build/$b" ]] || continue
  "$build/$b" --help >"$tmp/help" 2>&1 || fail "$b --help exit $?"
  grep -q "Exit status" "$tmp/help" || fail "$b --help does not list its exit statuses"
  "$build/$b" --no-such-option >/dev/null 2>&1; rc=$?
  ((rc == 2)) || fail "$b --no-such-option: exit $rc, expected 2"
done
# torque-dash's --help shows its defaults (address, page directory, period).
if [[ -x "$build/tools/torque-dash" ]]; then
  "$build/tools/torque-dash" --help >"$tmp/help" 2>&1
  grep -q "127.0.0.1:8080" "$tmp/help" && grep -q "share/torqued/www" "$tmp/help" && grep -Eq "period-ms.*=100" "$tmp/help" ||
    fail "torque-dash --help does not show its defaults: $(cat "$tmp/help")"
fi
# torque-accuracy: an unknown scenario is a command-line error that lists the known ones (not an abort).
if [[ -x "$build/tools/torque-accuracy" ]]; then
  "$build/tools/torque-accuracy" --scenario nosuch >/dev/null 2>"$tmp/err"; rc=$?
  ((rc == 2)) && grep -q "unknown scenario 'nosuch'; known: steady_1000_low" "$tmp/err" ||
    fail "torque-accuracy --scenario nosuch: exit $rc, $(head -c 300 "$tmp/err")"
fi
"$build/service/torqued" >/dev/null 2>"$tmp/err"; rc=$?
((rc == 2)) && grep -q "nothing to do: give --config" "$tmp/err" || fail "torqued without arguments: exit $rc, $(head -2 "$tmp/err")"
"$build/service/torqued" --config "$tmp/missing.yaml" >/dev/null 2>"$tmp/err"; rc=$?
((rc == 2)) && grep -q "does not exist" "$tmp/err" || fail "torqued --config missing: exit $rc, $(cat "$tmp/err")"

ev=$build/tools/torque-eval
printf 't_ns,fused_nm,brake_nm,quality\n' >"$tmp/est.csv"
awk 'BEGIN { for (i = 0; i < 20; i++) printf "%d,%d,%d,0\n", (i + 1) * 50000000, 103 + i, 103 + i }' >>"$tmp/est.csv"
awk 'BEGIN { print "cycle,t_start_s,t_end_s,t_brake_mean_nm,t_ind_mean_nm";
  for (i = 0; i < 20; i++) printf "%d,%.3f,%.3f,%d,%d\n", i, i * 0.05, (i + 1) * 0.05, 100 + i, 130 + i }' >"$tmp/truth.csv"
"$ev" -e "$tmp/est.csv" -t "$tmp/truth.csv" -c nope_nm=t_brake_mean_nm >/dev/null 2>"$tmp/err"; rc=$?
((rc == 1)) && grep -q "its columns are: t_ns, fused_nm, brake_nm, quality" "$tmp/err" ||
  fail "unknown estimate column: exit $rc, $(cat "$tmp/err")"
"$ev" -e "$tmp/missing.csv" -t "$tmp/truth.csv" -c a=b >/dev/null 2>&1; rc=$?
((rc == 2)) || fail "torque-eval with a missing file: exit $rc, expected 2"
out=$("$ev" -e "$tmp/est.csv" -t "$tmp/truth.csv" --time-ref end -c fused_nm=t_brake_mean_nm -c brake_nm=t_brake_mean_nm \
      -c fused_nm=t_ind_mean_nm --plot "$tmp/p.png" 2>&1) || fail "torque-eval: $out"
grep -q "max|err|" <<<"$out" && ! grep -q "MAE(max)" <<<"$out" || fail "accuracy column not named max|err|: $out"
(($(grep -c "^plot:" <<<"$out") == 1)) || fail "'plot:' not printed exactly once: $out"
head -c 8 "$tmp/p.png" | od -An -c | grep -q "P   N   G" || fail "no PNG written"
# Panels (pair names as torque-eval writes them in the plot CSV, "EST vs TRUTH"): two quantities (t_brake_mean_nm, t_ind_mean_nm); fused and brake identical -> one merged series.
/usr/bin/python3 - "$src/tools/scripts/plot_torque.py" <<'PY' || fail "plot grouping"
import importlib.util, sys
spec = importlib.util.spec_from_file_location("plot_torque", sys.argv[1]); m = importlib.util.module_from_spec(spec)
spec.loader.exec_module(m)
t = [0.0, 1.0]; s = {"fused_nm vs tb": (t, [1.0, 2.0], [1.5, 2.5]), "brake_nm vs tb": (t, [1.0, 2.0], [1.5, 2.5]),
                     "indicated_nm vs tb": (t, [3.0, 4.0], [1.5, 2.5]), "fused_nm vs ti": (t, [1.0, 2.0], [3.0, 3.0])}
g = m.by_quantity(s)
assert list(g) == ["tb", "ti"], g.keys()
assert [e[0] for e in g["tb"]] == ["fused_nm = brake_nm (identical)", "indicated_nm"], [e[0] for e in g["tb"]]
PY

# Paced replay: reports its end; exits (0) with replay.exit_when_done.
sed -e "s#\.\./data/demo#$src/data/demo#" -e "s#dbc: demo.dbc#dbc: $src/config/demo.dbc#" \
    -e "s#speed: 1.0#speed: 20.0\n  exit_when_done: true#" "$src/config/demo.yaml" >"$tmp/paced.yaml"
timeout 30 "$build/service/torqued" --config "$tmp/paced.yaml" --no-dds --fresh-state >"$tmp/paced.log" 2>&1; rc=$?
((rc == 0)) && grep -q "end of the recording reached; stopping" "$tmp/paced.log" ||
  fail "paced replay with replay.exit_when_done: exit $rc, $(tail -3 "$tmp/paced.log")"
# torque-latency: a --torqued that cannot be started, or a daemon that exits before the run's end, is said (the
# path and the log named) and exits 1 (it used to print a table of zeros); the logs stay in $TMPDIR.
if [[ -x "$build/tools/torque-latency" ]]; then
  export CYCLONEDDS_URI="file://$src/config/cyclonedds-loopback.xml"
  TMPDIR=$tmp "$build/tools/torque-latency" --torqued "$tmp/no-such-torqued" --config "$tmp/paced.yaml" \
    --duration 1 >"$tmp/lat.out" 2>&1; rc=$?
  ((rc == 1)) && grep -q "cannot start the daemon '$tmp/no-such-torqued': No such file or directory" "$tmp/lat.out" &&
    grep -q "log $tmp/torque-latency-.*/torqued.log" "$tmp/lat.out" ||
    fail "torque-latency --torqued missing: exit $rc, $(cat "$tmp/lat.out")"
  TMPDIR=$tmp "$build/tools/torque-latency" --torqued /bin/false --config "$tmp/paced.yaml" --duration 5 \
    >"$tmp/lat.out" 2>&1; rc=$?
  ((rc == 1)) && grep -q "the daemon '/bin/false' exited with status 1 before the run ended; see its log $tmp/" \
    "$tmp/lat.out" || fail "torque-latency --torqued /bin/false: exit $rc, $(cat "$tmp/lat.out")"
fi
echo "PASS"
