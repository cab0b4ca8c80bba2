#!/usr/bin/python3
"""Plot estimated vs true torque from torque-eval's long-format CSV (pair,t_s,est,truth).

Run with Debian's /usr/bin/python3 (python3-matplotlib); Agg backend, no display needed.
One panel per quantity (per truth column), each with its error panel right below:
  - estimates compared with the same truth share that panel; estimates that are identical sample for sample
    (e.g. brake_nm and fused_nm when fusion relies on the brake estimate alone) are drawn once, labelled
    "a = b (identical)";
  - the truth is drawn last, dashed black over the estimate, so a good estimate never hides it;
  - the error panel (estimate - truth) has its own scale, so small errors stay visible.
"""
import argparse
import csv
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLORS = ["tab:red", "tab:blue", "tab:green", "tab:orange", "tab:purple"]


def read(path):
    """pair name -> (t, est, truth) in file order."""
    series = OrderedDict()
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            s = series.setdefault(row["pair"], ([], [], []))
            s[0].append(float(row["t_s"]))
            s[1].append(float(row["est"]))
            s[2].append(float(row["truth"]))
    return series


def by_quantity(series):
    """truth column -> list of (label, t, est, truth); identical estimates merged into one entry."""
    groups = OrderedDict()
    for name, (t, est, truth) in series.items():
        sep = " vs " if " vs " in name else "="  # torque-eval writes "EST vs TRUTH"
        est_col, _, truth_col = (x.strip() for x in name.partition(sep))
        g = groups.setdefault(truth_col or name, [])
        for i, (label, t0, est0, truth0) in enumerate(g):
            if t0 == t and est0 == est:
                g[i] = (f"{label} = {est_col} (identical)", t0, est0, truth0)
                break
        else:
            g.append((est_col, t, est, truth))
    return groups


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="CSV written by torque-eval: pair,t_s,est,truth")
    ap.add_argument("--out", required=True, help="PNG file to write")
    ap.add_argument("--title", default="torqued: estimated vs true torque")
    args = ap.parse_args()

    series = read(args.data)
    if not series:
        print(f"{args.data}: no samples to plot", file=sys.stderr)
        return 1
    groups = by_quantity(series)
    n = len(groups)
    fig, axes = plt.subplots(2 * n, 1, figsize=(11, 3.6 * n), sharex=True, squeeze=False,
                             gridspec_kw={"height_ratios": [2.2, 1.0] * n})
    axes = axes[:, 0]
    for k, (quantity, entries) in enumerate(groups.items()):
        ax, err_ax = axes[2 * k], axes[2 * k + 1]
        for j, (label, t, est, truth) in enumerate(entries):
            color = COLORS[j % len(COLORS)]
            ax.plot(t, est, color=color, lw=1.4, alpha=0.8, label=f"estimate {label}", zorder=2)
            err_ax.plot(t, [e - y for e, y in zip(est, truth)], color=color, lw=0.9, label=label)
        t, truth = entries[0][1], entries[0][3]
        ax.plot(t, truth, color="black", lw=1.0, ls="--", label=f"truth {quantity}", zorder=3)
        ax.set_ylabel("torque (N m)")
        ax.set_title(quantity, fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
        err_ax.axhline(0.0, color="black", lw=0.6)
        err_ax.set_ylabel("error (N m)")
        err_ax.grid(alpha=0.3)
        if len(entries) > 1:
            err_ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time (s, edge clock)")
    fig.suptitle(args.title)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
