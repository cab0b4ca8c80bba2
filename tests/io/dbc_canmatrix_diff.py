#!/usr/bin/python3
"""Differential test of the DBC decoder: torque-decode against Debian's python3-canmatrix (an independent
decoder) on production DBC files (tests/data/dbc/opendbc, docs/io.md "DBC differential test").

For every message of every file, random payloads (plus all-zero and all-one ones) are written to one candump
log, decoded by `torque-decode --can LOG --dbc FILE --out-can CSV` and by canmatrix's Frame.decode(), and every
signal value is compared. A value agrees when both give the same number (integers exactly, scaled values within
1e-12 relative). Signals canmatrix cannot decode are left out and counted by reason:
  - past the DLC: the signal needs more bytes than the message declares (torqued skips it and counts the frame
    as "bad dlc"; canmatrix's bit slicing would read the wrong bits);
  - refused by torqued's parser: the DBC statement defining it is defective (reported with file:line).
Known canmatrix differences are counted separately and explained (--table prints the table of docs/io.md).
Exit status: 0 when every compared value agrees and the only differences are the known ones; 1 otherwise;
77 (skipped) when canmatrix is not installed.
"""
import argparse
import csv
import decimal
import glob
import logging
import math
import os
import random
import subprocess
import sys
import tempfile

try:
    import canmatrix.formats
except ImportError:  # opt-in: Debian's python3-canmatrix (tools/scripts/setup-deps.sh)
    print("dbc_canmatrix_diff: python3-canmatrix not installed: skipped")
    sys.exit(77)

# The known differences, each explained (docs/io.md "DBC differential test"). A change in either list fails.
# Signals torqued's parser refuses (each reported as file:line): names starting with a digit are no DBC
# identifiers (C identifiers, as Vector's DBC format defines them); canmatrix accepts them.
KNOWN_REFUSED = {
    "mazda_2017.dbc": ["2017_3.NEW_SIGNAL_1", "2017_5.counter", "2017_6.NEW_SIGNAL_1", "2017_7.NEW_SIGNAL_1",
                       "CRZ_CTRL.5_SEC_DISABLE_TIMER"],
    "psa_aee2010_r3.dbc": ["STEERING_ALT.0_CHECKSUM", "STEERING_ALT.0_COUNTER"],
}
# Messages where torqued decodes signals canmatrix leaves out: vw_pq's Motor_2 writes its multiplexor as 'm'
# (for 'M'); torqued takes it as the multiplexor with a warning, canmatrix drops that signal with an error
# ("error with line no: 394") and then decodes none of the signals it selects (m0..m3).
KNOWN_ONLY_TORQUED = {"vw_pq.dbc": ["Motor_2"]}

FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def fits(sig, size_bytes):
    """Whether canmatrix's bit slice of the signal lies inside the payload (canmatrix numbers Motorola bits
    MSB-first from bit 0 of byte 0, Intel bits from the LSB of byte 0)."""
    return 0 <= sig.start_bit and sig.start_bit + sig.size <= 8 * size_bytes


def payloads(frame, rng, n):
    size = frame.size
    out = [bytes(size), bytes([0xFF] * size)]
    out += [bytes(rng.getrandbits(8) for _ in range(size)) for _ in range(n)]
    return out


def candump_line(t_us, frame, data):
    aid = frame.arbitration_id
    ident = "%08X" % aid.id if aid.extended else "%03X" % aid.id
    sep = "##0" if len(data) > 8 else "#"
    return "(%d.%06d) can0 %s%s%s\n" % (t_us // 1000000, t_us % 1000000, ident, sep, data.hex().upper())


def canmatrix_values(frame, data, keep):
    """canmatrix's decode of the signals in `keep` (the others are taken out of the frame first)."""
    saved = frame.signals
    frame.signals = [s for s in saved if s.name in keep]
    try:
        decoded = frame.decode(bytearray(data))
    finally:
        frame.signals = saved
    return {name: d for name, d in decoded.items() if name in keep}


def agrees(text, decoded):
    sig = decoded.signal
    expected = decoded.phys_value
    if isinstance(expected, int) or (isinstance(expected, decimal.Decimal) and expected == expected.to_integral()
                                     and "." not in text and "e" not in text):
        try:
            return int(text) == int(expected)
        except ValueError:
            pass
    got = float(text)
    exp = float(expected)
    if math.isnan(exp) or math.isnan(got):
        return math.isnan(exp) and math.isnan(got)
    scale = max(abs(float(sig.factor)), abs(float(sig.offset)), 1e-300)
    return math.isclose(got, exp, rel_tol=1e-12, abs_tol=1e-12 * scale)


def run_file(path, exe, n_payloads, seed, workdir):
    logging.disable(logging.CRITICAL)
    db = canmatrix.formats.loadp_flat(path, dbcImportEncoding="cp1252")
    rng = random.Random(seed)
    frames, log = [], []
    t_us = 1000
    for frame in db.frames:
        if not frame.signals or (frame.size > 8 and frame.size not in FD_LENGTHS):
            continue
        for data in payloads(frame, rng, n_payloads):
            frames.append((t_us * 1000, frame, data))
            log.append(candump_line(t_us, frame, data))
            t_us += 1000
    log_path = os.path.join(workdir, "can.log")
    out_path = os.path.join(workdir, "can.csv")
    with open(log_path, "w") as f:
        f.writelines(log)
    run = subprocess.run([exe, "-q", "--can", log_path, "--dbc", path, "--out-can", out_path],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace")
    if run.returncode != 0:
        raise RuntimeError("torque-decode failed on %s: %s" % (path, run.stderr[-2000:]))
    tq = {}
    with open(out_path, newline="", encoding="latin-1") as f:
        for row in csv.DictReader(f):
            tq[(int(row["t_ns"]), row["signal"])] = row["value"]
    seen_by_tq = {}
    for (t, sig) in tq:
        seen_by_tq.setdefault(t, set()).add(sig)
    st = dict(file=os.path.basename(path), messages=0, signals=0, values=0, agree=0, mismatch=0,
              past_dlc=0, refused=0, mux_canmatrix=0, examples=[])
    refused_signals, only_tq = set(), set()
    counted = set()
    for t_ns, frame, data in frames:
        if frame.name not in counted:
            counted.add(frame.name)
            st["messages"] += 1
            st["signals"] += len(frame.signals)
        keep = {s.name for s in frame.signals if fits(s, len(data))}
        st["past_dlc"] += len(frame.signals) - len(keep)
        cm = canmatrix_values(frame, data, keep)
        got = seen_by_tq.get(t_ns, set())
        for name, d in cm.items():
            if name not in got:
                # canmatrix decodes it, torqued does not: refused by torqued's parser or a mux difference
                refused_signals.add((frame.name, name))
                continue
            st["values"] += 1
            if agrees(tq[(t_ns, name)], d):
                st["agree"] += 1
            else:
                st["mismatch"] += 1
                if len(st["examples"]) < 5:
                    st["examples"].append("%s.%s data %s: torqued %s, canmatrix %s" %
                                          (frame.name, name, data.hex(), tq[(t_ns, name)], d.phys_value))
        for name in got - set(cm):
            only_tq.add(frame.name)
            st["mux_canmatrix"] += 1  # torqued decodes a signal canmatrix leaves out of this payload
            if len(st["examples"]) < 5:
                st["examples"].append("%s.%s data %s: only torqued (%s)" % (frame.name, name, data.hex(),
                                                                            tq[(t_ns, name)]))
    st["refused"] = len(refused_signals)
    st["refused_names"] = sorted("%s.%s" % k for k in refused_signals)
    st["only_tq_messages"] = sorted(only_tq)
    st["stderr"] = run.stderr
    return st


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--torque-decode", required=True)
    ap.add_argument("--dir", required=True, help="folder of .dbc files")
    ap.add_argument("--payloads", type=int, default=30, help="random payloads per message")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--table", action="store_true", help="print the docs/io.md table")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for path in sorted(glob.glob(os.path.join(a.dir, "*.dbc"))):
            rows.append(run_file(path, a.torque_decode, a.payloads, a.seed, work))
    ok = True
    print("| file | messages | signals | values compared | agree | mismatches | values past the DLC (both skip) | "
          "signals torqued refuses | values only torqued decodes |")
    print("|---|---|---|---|---|---|---|---|---|")
    tot = {k: 0 for k in ("messages", "signals", "values", "agree", "mismatch", "past_dlc", "refused",
                          "mux_canmatrix")}
    for r in rows:
        print("| %s | %d | %d | %d | %d | %d | %d | %d | %d |" % (
            r["file"], r["messages"], r["signals"], r["values"], r["agree"], r["mismatch"], r["past_dlc"],
            r["refused"], r["mux_canmatrix"]))
        for k in tot:
            tot[k] += r[k]
        if r["mismatch"] or a.verbose:
            for e in r["examples"]:
                print("    " + e, file=sys.stderr)
        if a.verbose:
            for n in r["refused_names"]:
                print("    refused: " + n, file=sys.stderr)
        ok = ok and r["mismatch"] == 0
        for what, got, known in (("refused by torqued", r["refused_names"], KNOWN_REFUSED),
                                 ("decoded by torqued only", r["only_tq_messages"], KNOWN_ONLY_TORQUED)):
            if got != known.get(r["file"], []):
                print("%s: %s: %s, expected %s" % (r["file"], what, got, known.get(r["file"], [])),
                      file=sys.stderr)
                ok = False
    print("| all | %d | %d | %d | %d | %d | %d | %d | %d |" % tuple(tot[k] for k in tot))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
