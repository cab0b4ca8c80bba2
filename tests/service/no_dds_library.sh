#!/bin/sh
# tests/service/no_dds_library.sh TORQUED SOURCE_DIR WORK_DIR: a `--no-dds` fast replay of the demo does not
# load Cyclone DDS's library (service/ddsc_lazy.cpp opens it on the first DDS call; linked normally, it and its
# libcrypto, libssl and iceoryx libraries were a quarter of the start-up's instructions). Read from the dynamic
# loader's own record of the files it opened (LD_DEBUG=files, written to files, not parsed from stderr): it
# names libyaml-cpp (the record is there) and no libddsc. The runs with DDS, which do load it, are the
# integration tests (EndToEnd.*, Service.*, DdsSecurity.*).
set -u
TORQUED=$1
SRC=$2
WORK=$3/no_dds_library
rm -rf "$WORK" && mkdir -p "$WORK" || exit 1
if ! (cd "$SRC" && LD_DEBUG=files LD_DEBUG_OUTPUT="$WORK/ld" "$TORQUED" --config config/demo.yaml \
      --replay fast --no-dds --fresh-state --state-dir "$WORK/state" >"$WORK/out.log" 2>"$WORK/err.log"); then
  echo "FAIL: the --no-dds replay failed (exit != 0): $WORK/err.log"
  exit 1
fi
if ! cat "$WORK"/ld.* 2>/dev/null | grep -q "file=libyaml-cpp"; then
  echo "FAIL: no loader record in $WORK/ld.* (LD_DEBUG=files ignored?)"
  exit 1
fi
if cat "$WORK"/ld.* | grep -q "file=libddsc"; then
  echo "FAIL: a --no-dds run loaded libddsc:"
  cat "$WORK"/ld.* | grep "file=libddsc" | head -3
  exit 1
fi
echo "ok: --no-dds loaded no libddsc"
