#!/usr/bin/env bash
# Golden output: the demo's fast replay (deterministic, byte-identical by design) compared byte for byte with
# the recording committed in tests/golden/demo/ (gzip -n). A refactoring must leave it unchanged; a change of
# behaviour updates it in a commit that says why:
#   tests/golden/golden_demo.sh build/service/torqued . --update
# Exit: 0 identical (or updated), 1 a file differs or is missing (the first differing lines are printed),
# 2 usage or the replay failed.
set -euo pipefail
torqued=${1:?usage: golden_demo.sh TORQUED SOURCE_DIR [--update]}
src=${2:?usage: golden_demo.sh TORQUED SOURCE_DIR [--update]}
update=${3:-}
golden="$src/tests/golden/demo"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
export CYCLONEDDS_URI=${CYCLONEDDS_URI:-file://$src/config/cyclonedds-loopback.xml}
if ! (cd "$src" && "$torqued" --config config/demo.yaml --replay fast --no-dds --fresh-state --state-dir "$tmp/state" \
      --record "$tmp/rec" >"$tmp/log" 2>&1); then
  echo "golden_demo: the replay failed:"; cat "$tmp/log"; exit 2
fi
if [[ "$update" == "--update" ]]; then
  rm -rf "$golden"; mkdir -p "$golden"
  for f in "$tmp"/rec/*.csv; do gzip -9 -n -c "$f" >"$golden/$(basename "$f").gz"; done
  echo "golden_demo: updated $(ls "$golden" | wc -l) files in $golden"; exit 0
fi
status=0
for g in "$golden"/*.csv.gz; do
  name=$(basename "$g" .gz)
  if [[ ! -f "$tmp/rec/$name" ]]; then echo "golden_demo: $name missing from the replay's recording"; status=1; continue; fi
  if ! zcat "$g" | cmp -s - "$tmp/rec/$name"; then
    echo "golden_demo: $name differs from $g (golden < > now):"
    diff <(zcat "$g") "$tmp/rec/$name" | head -8 || true
    status=1
  fi
done
for f in "$tmp"/rec/*.csv; do
  [[ -f "$golden/$(basename "$f").gz" ]] || { echo "golden_demo: new file $(basename "$f") has no golden copy"; status=1; }
done
((status == 0)) && echo "golden_demo: $(ls "$golden" | wc -l) files identical"
exit $status
