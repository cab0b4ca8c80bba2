#!/usr/bin/python3
"""Plot torque-decode's per-tooth CSV: speed per tooth, per-revolution speed, gaps, glitches and sync losses.

Run with Debian's /usr/bin/python3 (python3-matplotlib); Agg backend, no display needed. torque-decode --plot
calls it; by hand:  plot_decode.py --teeth teeth.csv --teeth-per-rev 58 --out decode.png
Input columns: t_ns,t_s,tooth,angle_deg,rpm,sync,phase_known,events (events: noise|lost_tooth|resync|gap).
"""
import argparse
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--teeth", required=True, help="per-tooth CSV written by torque-decode --out-teeth")
    ap.add_argument("--teeth-per-rev", type=int, required=True, help="teeth per crank revolution")
    ap.add_argument("--out", required=True, help="PNG file to write")
    ap.add_argument("--title", default="torque-decode")
    args = ap.parse_args()

    synced, syncing, gaps, noise, lost, resync, losses, stalls, revs = [], [], [], [], [], [], [], [], []
    last_t0 = None
    with open(args.teeth, newline="") as f:
        for row in csv.DictReader(f):
            t, rpm, state, ev = float(row["t_s"]), float(row["rpm"]), row["sync"], row["events"]
            tooth = int(row["tooth"])
            if state == "synced":
                synced.append((t, rpm))
                if tooth % args.teeth_per_rev == 0:
                    if last_t0 is not None:
                        revs.append((last_t0, t, 60.0 / (t - last_t0)))
                    last_t0 = t
            else:
                last_t0 = None
                if state == "lost_sync":
                    losses.append(t)
                elif state == "stalled":
                    stalls.append(t)
                elif rpm > 0:
                    syncing.append((t, rpm))
            if "gap" in ev:
                gaps.append((t, rpm))
            if "noise" in ev:
                noise.append((t, rpm))
            if "lost_tooth" in ev:
                lost.append((t, rpm))
            if "resync" in ev:
                resync.append(t)
    if not synced and not syncing:
        print(f"{args.teeth}: no teeth to plot", file=sys.stderr)
        return 1

    fig, ax = plt.subplots(figsize=(12, 5))
    if syncing:
        ax.plot(*zip(*syncing), ".", color="0.6", ms=3, label="syncing (pitch / period)")
    if synced:
        ax.plot(*zip(*synced), "-", color="tab:blue", lw=0.8, label="speed per tooth (synced)")
    for i, (t0, t1, rpm) in enumerate(revs):
        ax.hlines(rpm, t0, t1, color="black", lw=1.6, label="per revolution" if i == 0 else None)
    if gaps:
        ax.plot(*zip(*gaps), "v", color="tab:green", ms=4, label="gap")
    if noise:
        ax.plot(*zip(*noise), "x", color="tab:red", ms=7, label="glitch / noise edge rejected")
    if lost:
        ax.plot(*zip(*lost), "s", color="tab:orange", ms=5, label="lost tooth interpolated")
    for i, t in enumerate(losses):
        ax.axvline(t, color="tab:red", lw=1.2, ls="--", label="sync lost" if i == 0 else None)
    for i, t in enumerate(resync):
        ax.axvline(t, color="tab:green", lw=1.0, ls=":", label="resynced" if i == 0 else None)
    for i, t in enumerate(stalls):
        ax.axvline(t, color="tab:purple", lw=1.0, ls="-.", label="stall" if i == 0 else None)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("crank speed (rpm)")
    ax.set_title(args.title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
