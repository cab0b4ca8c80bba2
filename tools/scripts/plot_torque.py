#!/usr/bin/python3
"""Plot estimated vs true torque from torque-eval's long-format CSV (pair,t_s,est,truth).

Run with Debian's /usr/bin/python3 (python3-matplotlib); Agg backend, no display needed.
One panel per column pair (estimate and truth over time) plus one panel of the errors.
"""
import argparse
import csv
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--data", required=True, help="CSV written by torque-eval: pair,t_s,est,truth")
    ap.add_argument("--out", required=True, help="PNG file to write")
    ap.add_argument("--title", default="torqued: estimated vs true torque")
    args = ap.parse_args()

    series = OrderedDict()
    with open(args.data, newline="") as f:
        for row in csv.DictReader(f):
            s = series.setdefault(row["pair"], ([], [], []))
            s[0].append(float(row["t_s"]))
            s[1].append(float(row["est"]))
            s[2].append(float(row["truth"]))
    if not series:
        print(f"{args.data}: no samples to plot", file=sys.stderr)
        return 1

    n = len(series)
    fig, axes = plt.subplots(n + 1, 1, figsize=(11, 2.6 * (n + 1)), sharex=True, squeeze=False)
    axes = axes[:, 0]
    for ax, (name, (t, est, truth)) in zip(axes, series.items()):
        ax.plot(t, truth, color="black", lw=1.2, label="truth")
        ax.plot(t, est, color="tab:red", lw=0.9, alpha=0.85, label="estimate")
        ax.set_ylabel("torque (N m)")
        ax.set_title(name, fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    err_ax = axes[-1]
    for name, (t, est, truth) in series.items():
        err_ax.plot(t, [e - y for e, y in zip(est, truth)], lw=0.8, label=name)
    err_ax.axhline(0.0, color="black", lw=0.6)
    err_ax.set_ylabel("error (N m)")
    err_ax.set_xlabel("time (s, edge clock)")
    err_ax.grid(alpha=0.3)
    err_ax.legend(loc="upper right", fontsize=7)
    fig.suptitle(args.title)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
