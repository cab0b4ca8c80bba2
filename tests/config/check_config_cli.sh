#!/bin/sh
# ctest: `torqued --check-config` accepts a good file (exit 0, "OK") and refuses a bad one (exit 1, file:line:col).
set -u
torqued=$1
dir=$(dirname "$0")
out=$("$torqued" --check-config "$dir/good/files.yaml" 2>&1); rc=$?
[ $rc -eq 0 ] || { echo "good file: exit $rc, expected 0: $out"; exit 1; }
echo "$out" | grep -q "files.yaml: OK (3 cylinders, wheel 36-1" || { echo "good file: unexpected output: $out"; exit 1; }
out=$("$torqued" --check-config "$dir/bad/negative_bore.yaml" 2>&1); rc=$?
[ $rc -eq 1 ] || { echo "bad file: exit $rc, expected 1: $out"; exit 1; }
echo "$out" | grep -qF "negative_bore.yaml:4:11: key 'engine.bore_m': found '-0.08', expected a finite number (m, range (0, 1])" \
  || { echo "bad file: unexpected message: $out"; exit 1; }
out=$("$torqued" --check-config "$dir/bad/many_errors.yaml" 2>&1); rc=$?
[ $rc -eq 1 ] && echo "$out" | grep -q "6 error(s)" || { echo "many errors: exit $rc: $out"; exit 1; }
echo "check-config CLI OK"
