#!/usr/bin/python3
"""Plot torque-latency's measurements: latency distributions of the daemon's samples next to cyclictest's.

Input: the CSV torque-latency writes next to the PNG (series,us,count): one row per received sample (count 1)
for the series crank_total, crank_daemon, crank_dds, engine_total, and cyclictest's histogram bins
(series cyclictest, count per 1 us bin). Run with Debian's /usr/bin/python3 (python3-matplotlib), Agg backend.
Left: complementary CDF (share of samples later than x, log scale: the tail is what p99.9 is about).
Right: histogram of the first 400 us (where p50 lives) with the p50 target.
"""
import argparse
import csv
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

LABELS = {
    "crank_total": "tooth edge -> CrankState received",
    "crank_daemon": "  edge -> dds_write (daemon)",
    "crank_dds": "  dds_write -> received (DDS)",
    "engine_total": "tooth edge -> EngineTorque received",
    "cyclictest": "cyclictest (one timer wake-up, same run)",
}
STYLES = {
    "crank_total": dict(color="C0", lw=2.0),
    "crank_daemon": dict(color="C0", lw=1.0, ls="--"),
    "crank_dds": dict(color="C0", lw=1.0, ls=":"),
    "engine_total": dict(color="C2", lw=1.2),
    "cyclictest": dict(color="C3", lw=1.5),
}


def percentile(xs, ws, p):
    total = sum(ws)
    acc = 0
    for x, w in zip(xs, ws):
        acc += w
        if acc >= p / 100.0 * total:
            return x
    return xs[-1] if xs else 0.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", required=True, help="CSV written by torque-latency: series,us,count")
    ap.add_argument("--out", required=True, help="PNG file to write")
    ap.add_argument("--title", default="torqued: tooth edge -> subscriber latency")
    ap.add_argument("--target-p50", type=float, default=50.0, help="p50 target (us)")
    args = ap.parse_args()

    series = OrderedDict()
    with open(args.data, newline="") as f:
        for row in csv.DictReader(f):
            s = series.setdefault(row["series"], {})
            us = float(row["us"])
            s[us] = s.get(us, 0) + int(row["count"])
    if not series:
        print(f"plot_latency: no data in {args.data}", file=sys.stderr)
        return 1

    fig, (ax_tail, ax_hist) = plt.subplots(1, 2, figsize=(13, 5.2))
    p999 = {}
    for name, hist in series.items():
        xs = sorted(hist)
        ws = [hist[x] for x in xs]
        total = float(sum(ws))
        if total <= 0:
            continue
        p50, p999[name] = percentile(xs, ws, 50), percentile(xs, ws, 99.9)
        label = f"{LABELS.get(name, name)}: p50 {p50:.0f}, p99.9 {p999[name]:.0f} us (n={int(total)})"
        later, acc = [], 0
        for w in ws:
            acc += w
            later.append(max(1.0 - acc / total, 0.5 / total))
        style = STYLES.get(name, {})
        ax_tail.step(xs, later, where="post", label=label, **style)
        lo = [x for x in xs if x <= 400]
        if name in ("crank_total", "cyclictest") and lo:
            ax_hist.hist(
                lo,
                bins=80,
                range=(0, 400),
                weights=[hist[x] / total for x in lo],
                histtype="step",
                lw=1.5,
                color=style.get("color"),
                label=LABELS.get(name, name),
            )
    ax_tail.set_xscale("log")
    ax_tail.set_yscale("log")
    ax_tail.axhline(1e-3, color="grey", lw=0.8, ls=":")
    ax_tail.text(ax_tail.get_xlim()[0] * 1.1, 1.15e-3, "p99.9", color="grey", fontsize=8)
    if "cyclictest" in p999:
        ax_tail.axvline(2 * p999["cyclictest"], color="C3", lw=0.8, ls="--")
        ax_tail.text(2 * p999["cyclictest"] * 1.05, 0.3, "2x cyclictest p99.9\n(p99.9 target)", color="C3", fontsize=8)
    ax_tail.set_xlabel("latency (us)")
    ax_tail.set_ylabel("share of samples later than x")
    ax_tail.grid(True, which="both", alpha=0.3)
    ax_tail.legend(fontsize=7, loc="lower left")
    ax_hist.axvline(args.target_p50, color="k", lw=0.8, ls="--")
    ax_hist.text(args.target_p50 + 3, ax_hist.get_ylim()[1] * 0.9, "p50 target", fontsize=8)
    ax_hist.set_xlabel("latency (us), first 400 us")
    ax_hist.set_ylabel("share of samples per 5 us")
    ax_hist.grid(True, alpha=0.3)
    ax_hist.legend(fontsize=8)
    fig.suptitle(args.title)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
