#!/usr/bin/env python3
"""Where the in-cycle Kalman's error lives: decomposes a per-tooth dump of the unseen bed's fresh start
(`torque-accuracy --bed unseen --bed-incycle --bed-engine NAME --bed-incycle-dump FILE`) over the scored
window (docs/angle_estimators.md, "What limits the I6"):

  (a) by engine order: a DFT over each complete 720-degree cycle of the error; each order's share of the
      mean square, as an RMS in % of the mean per-cycle peak-to-peak of the true indicated torque;
  (b) by crank angle within a firing interval, relative to the last firing TDC (found from the truth's
      per-cylinder torque: its sign change from compression to expansion);
  (c) the same for the gas model's own ripple (the observers' known input, before any correction) against
      the truth's ripple (the truth minus its cycle mean, averaged over the tooth step the model describes).

Usage: incycle_orders.py DUMP.csv [DUMP2.csv ...]   (one table per file; standard library only)
"""
import csv
import math
import sys

ORDERS = [0.5, 1.0, 1.5, 2.0, 3.0, 4.5, 6.0, 9.0, 12.0, 15.0, 18.0]


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ncyl = sum(1 for k in rows[0] if k.startswith("t_cyl"))
    return rows, ncyl


def cycles_of(rows):
    """Complete cycles of the scored window, each a list of rows ordered by tooth."""
    by = {}
    for r in rows:
        by.setdefault(int(r["cycle"]), []).append(r)
    teeth = max(len(v) for v in by.values())
    out = []
    for c in sorted(by):
        v = by[c]
        if len(v) != teeth or not all(r["scored"] == "1" for r in v):
            continue
        if any(math.isnan(float(r["kalman_nm"])) for r in v):
            continue
        out.append(sorted(v, key=lambda r: int(r["tooth"])))
    return out


def firing_tdcs(rows, ncyl):
    """Each cylinder's firing TDC (deg in 720): where its torque turns from negative to positive and stays
    large (the firing one of its two TDCs), from the first complete cycle."""
    tdc = []
    for c in range(ncyl):
        key = "t_cyl%d_nm" % (c + 1)
        best, where = 0.0, 0.0
        for i in range(1, len(rows)):
            a, b = float(rows[i - 1][key]), float(rows[i][key])
            if a < 0.0 <= b and b - a > best and int(rows[i]["cycle"]) == int(rows[i - 1]["cycle"]):
                best = b - a
                a0, a1 = float(rows[i - 1]["angle720_deg"]), float(rows[i]["angle720_deg"])
                where = a0 + (a1 - a0) * (-a) / (b - a)
        tdc.append(where)
    return sorted(tdc)


def dft_rms(series, angles, order):
    """RMS (same unit) of the component at `order` per revolution of a 720-degree cycle's samples, each at
    its own crank angle (deg in 720; the teeth are not equally spaced: a wheel's gap), the sum weighted by
    the angle each sample stands for (half the span to each neighbour)."""
    n = len(series)
    h = order * 2.0
    w = [((angles[(i + 1) % n] - angles[i - 1]) % 720.0) / 2.0 for i in range(n)]
    tot = sum(w)
    ph = [2.0 * math.pi * h * a / 720.0 for a in angles]
    re = sum(x * wi * math.cos(p) for x, wi, p in zip(series, w, ph)) / tot
    im = sum(x * wi * math.sin(p) for x, wi, p in zip(series, w, ph)) / tot
    amp = 2.0 * math.hypot(re, im) if h > 0 else abs(re)
    return amp / math.sqrt(2.0) if h > 0 else amp


def analyse(path):
    rows, ncyl = load(path)
    cyc = cycles_of(rows)
    if not cyc:
        print("%s: no complete scored cycle" % path)
        return
    tdcs = firing_tdcs([r for c in cyc[:1] for r in c], ncyl)
    interval = 720.0 / ncyl
    p2p = sum(max(float(r["t_ind_nm"]) for r in c) - min(float(r["t_ind_nm"]) for r in c) for c in cyc)
    p2p /= len(cyc)
    ke, me, ang = [], [], []  # per cycle: Kalman error, model ripple error, crank angle (per tooth)
    for c in cyc:
        t = [float(r["t_ind_nm"]) for r in c]
        mean_t = sum(t) / len(t)
        # the model's ripple describes the step after tooth k: the truth's mean over that step
        t_step = [0.5 * (t[i] + t[(i + 1) % len(t)]) - mean_t for i in range(len(t))]
        ke.append([float(r["kalman_nm"]) - x for r, x in zip(c, t)])
        ang.append([float(r["angle720_deg"]) for r in c])
        me.append([float(r["ripple_nm"]) - x for r, x in zip(c, t_step)])
    n_all = sum(len(e) for e in ke)
    k_rms = math.sqrt(sum(x * x for e in ke for x in e) / n_all)
    m_rms = math.sqrt(sum(x * x for e in me for x in e) / n_all)
    print("%s: %d cycles, %d cylinders, p2p %.1f N m, firing TDCs %s deg" %
          (path, len(cyc), ncyl, p2p, " ".join("%.1f" % x for x in tdcs)))
    print("Kalman error RMS %.2f %% of p2p; gas model ripple vs truth ripple RMS %.2f %%" %
          (100 * k_rms / p2p, 100 * m_rms / p2p))
    print("\n(a) by order (RMS % of p2p; per-cycle DFT, root of the mean square over cycles)")
    print("| order | Kalman error | model error |")
    print("|---|---|---|")
    for o in ORDERS:
        kk = math.sqrt(sum(dft_rms(e, a, o) ** 2 for e, a in zip(ke, ang)) / len(ke))
        mm = math.sqrt(sum(dft_rms(e, a, o) ** 2 for e, a in zip(me, ang)) / len(me))
        print("| %g | %.2f | %.2f |" % (o, 100 * kk / p2p, 100 * mm / p2p))
    print("\n(b) by crank angle after the last firing TDC (deg; RMS % of p2p, mean error % of p2p)")
    print("| window | Kalman RMS | Kalman mean | model RMS | model mean | share of Kalman MS |")
    print("|---|---|---|---|---|---|")
    nb = 8
    width = interval / nb
    acc = [[0.0, 0.0, 0.0, 0.0, 0] for _ in range(nb)]
    for c, ek, em in zip(cyc, ke, me):
        for r, a, b in zip(c, ek, em):
            ang = float(r["angle720_deg"])
            rel = min(((ang - t) % 720.0 for t in tdcs))
            j = min(int(rel / width), nb - 1)
            acc[j][0] += a * a
            acc[j][1] += a
            acc[j][2] += b * b
            acc[j][3] += b
            acc[j][4] += 1
    tot = sum(x[0] for x in acc)
    for j, (ka2, ka, ma2, ma, n) in enumerate(acc):
        if n == 0:
            continue
        print("| %3.0f-%3.0f | %.2f | %+.2f | %.2f | %+.2f | %.0f %% |" %
              (j * width, (j + 1) * width, 100 * math.sqrt(ka2 / n) / p2p, 100 * ka / n / p2p,
               100 * math.sqrt(ma2 / n) / p2p, 100 * ma / n / p2p, 100 * ka2 / tot))
    print()


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for p in sys.argv[1:]:
        analyse(p)
