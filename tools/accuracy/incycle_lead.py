#!/usr/bin/env python3
"""Where and why the in-cycle Kalman's estimate leads or lags the truth: reads a per-tooth dump of the unseen
bed (`torque-accuracy --bed unseen --bed-incycle-regimes --bed-engine NAME --bed-incycle-regimes-dump FILE`, or
the fresh start's `--bed-incycle-dump`; columns in docs/eval.md) and splits the lag (docs/angle_estimators.md,
"Why the I6's estimate leads"):

  (a) per scored window and per class of cycle (steady; speed changing; MAP changing; cut-off, where the truth's
      cycle has no firing), the lag of the Kalman's estimate E and of its known part alone M (the gas model's
      ripple plus the extended load inside E: what E would be with no correction), by the bed's rule (the
      shift of the whole series, in teeth x the wheel's step, that maximises the cross-correlation with the
      truth; + behind); and the same at the firing order only (phase of the per-cycle DFT, deg of crank);
  (b) by crank angle after the last firing TDC, the mean of E - T, of M - T and of the correction X = E - M
      (% of the mean per-cycle p2p of the truth), steady against changing cycles.

A class: per complete cycle, |d speed/dt| >= SPEED_RATE rpm/s makes it "speed", else |d MAP/dt| >=
MAP_RATE kPa/s makes it "map", else "steady" (the rates over the cycle, first to last tooth); a cycle whose
truth has no positive per-cylinder work (no firing: the cut-off) is "cut".

Usage: incycle_lead.py DUMP.csv [--step DEG] [--speed-rate R] [--map-rate R] (standard library only)
"""
import argparse
import math

import incycle_orders as io_

MAX_SHIFT = 12


def lag_deg(est, tru, idx, step):
    """The bed's lag (tools/accuracy/cylinder_eval.cpp incycle_stats) over the rows `idx` of the whole run:
    est[i] against tru[i - s], s in +-MAX_SHIFT teeth, parabola-refined; + behind."""
    idx = [i for i in idx if MAX_SHIFT <= i < len(est) - MAX_SHIFT]
    if len(idx) < 100:
        return float("nan")
    me = sum(est[i] for i in idx) / len(idx)
    mt = sum(tru[i] for i in idx) / len(idx)
    cc = []
    for s in range(-MAX_SHIFT, MAX_SHIFT + 1):
        cc.append(sum((est[i] - me) * (tru[i - s] - mt) for i in idx))
    b = max(range(len(cc)), key=lambda j: cc[j])
    frac = 0.0
    if 0 < b < len(cc) - 1:
        den = cc[b - 1] - 2 * cc[b] + cc[b + 1]
        if den != 0.0:
            frac = 0.5 * (cc[b - 1] - cc[b + 1]) / den
    return (b - MAX_SHIFT + frac) * step


def phasor(series, angles, order):
    """Complex amplitude at `order` per revolution (angle-weighted DFT over one 720-degree cycle)."""
    n = len(series)
    w = [((angles[(i + 1) % n] - angles[i - 1]) % 720.0) / 2.0 for i in range(n)]
    tot = sum(w)
    re = im = 0.0
    for x, wi, a in zip(series, w, angles):
        p = 2.0 * math.pi * order * a / 360.0
        re += x * wi * math.cos(p)
        im -= x * wi * math.sin(p)
    return complex(re, im) / tot


def phase_lag_deg(p_est, p_tru, order):
    """Crank degrees by which the estimate's component is behind the truth's (+ behind)."""
    if abs(p_est) == 0.0 or abs(p_tru) == 0.0:
        return float("nan")
    d = math.atan2((p_est / p_tru).imag, (p_est / p_tru).real)
    return -d * 360.0 / (2.0 * math.pi * order)


def classify(cyc, ncyl, speed_rate, map_rate):
    t0, t1 = float(cyc[0]["t_s"]), float(cyc[-1]["t_s"])
    dt = max(t1 - t0, 1e-6)
    fired = any(float(r["t_cyl%d_nm" % (c + 1)]) > 0.0 for r in cyc for c in range(ncyl)) and max(
        float(r["t_ind_nm"]) for r in cyc) > 0.0
    work = sum(float(r["t_ind_nm"]) for r in cyc) / len(cyc)
    if not fired or work < 0.0:
        return "cut"
    ds = abs(float(cyc[-1]["speed_rpm"]) - float(cyc[0]["speed_rpm"])) / dt
    dm = abs(float(cyc[-1]["map_pa"]) - float(cyc[0]["map_pa"])) / 1000.0 / dt
    if ds >= speed_rate:
        return "speed"
    if dm >= map_rate:
        return "map"
    return "steady"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dump")
    ap.add_argument("--step", type=float, default=0.0, help="deg per tooth (default 720 / rows per cycle)")
    ap.add_argument("--speed-rate", type=float, default=300.0, help="rpm/s: a 'speed' cycle")
    ap.add_argument("--map-rate", type=float, default=20.0, help="kPa/s: a 'map' cycle")
    a = ap.parse_args()
    rows, ncyl = io_.load(a.dump)
    f = lambda k: [float(r[k]) for r in rows]  # noqa: E731
    T, E = f("t_ind_nm"), f("kalman_nm")
    M = [m + l for m, l in zip(f("kalman_model_nm"), f("kalman_load_nm"))]
    by = {}
    for i, r in enumerate(rows):
        by.setdefault(int(r["cycle"]), []).append(i)
    teeth = max(len(v) for v in by.values())
    positions = {58: 60, 35: 36, 34: 36}.get(teeth // 2, teeth // 2)  # the bed's wheels: 60-2, 36-1, 36-2
    step = a.step if a.step > 0 else 360.0 / positions
    order = ncyl / 2.0
    # complete cycles, each scored in one window, every estimate there
    cycles = []
    for c in sorted(by):
        ix = by[c]
        if len(ix) != teeth or any(math.isnan(E[i]) or math.isnan(M[i]) for i in ix):
            continue
        for w in (1, 2):  # bit mask: the regimes' windows overlap
            if all(int(rows[i]["scored"]) & w for i in ix):
                cycles.append((w, ix))
    if not cycles:
        raise SystemExit("%s: no complete scored cycle" % a.dump)
    tdcs = io_.firing_tdcs([rows[i] for _, ix in cycles[:1] for i in ix], ncyl)
    groups = {}
    for w, ix in cycles:
        cl = classify([rows[i] for i in ix], ncyl, a.speed_rate, a.map_rate)
        groups.setdefault((w, cl), []).append(ix)
        groups.setdefault((w, "all"), []).append(ix)
    print("%s: %d scored cycles (of windows), %d cylinders, %.2f deg per tooth, firing TDCs %s" %
          (a.dump, len(cycles), ncyl, step, " ".join("%.1f" % x for x in tdcs)))
    print("\n(a) lag (deg, + behind) of the estimate E and of its known part M (gas model + extended load), the"
          "\nwhole series (the bed's rule) and at the firing order %g; RMS of E - T and M - T (%% of p2p)" % order)
    print("| window | class | cycles | E lag | M lag | E lag order %g | M lag order %g | E RMS | M RMS |" %
          (order, order))
    print("|---|---|---|---|---|---|---|---|---|")
    for (w, cl) in sorted(groups, key=lambda k: (k[0], ["all", "steady", "speed", "map", "cut"].index(k[1]))):
        cs = groups[(w, cl)]
        idx = [i for ix in cs for i in ix]
        p2p = sum(max(T[i] for i in ix) - min(T[i] for i in ix) for ix in cs) / len(cs)
        pe = pm = 0.0
        le, lm = [], []
        for ix in cs:
            ang = [float(rows[i]["angle720_deg"]) for i in ix]
            pt = phasor([T[i] for i in ix], ang, order)
            le.append(phase_lag_deg(phasor([E[i] for i in ix], ang, order), pt, order))
            lm.append(phase_lag_deg(phasor([M[i] for i in ix], ang, order), pt, order))
        le = [x for x in le if not math.isnan(x)]
        lm = [x for x in lm if not math.isnan(x)]
        pe = sum(le) / len(le) if le else float("nan")
        pm = sum(lm) / len(lm) if lm else float("nan")
        er = math.sqrt(sum((E[i] - T[i]) ** 2 for i in idx) / len(idx))
        mr = math.sqrt(sum((M[i] - T[i]) ** 2 for i in idx) / len(idx))
        print("| %s | %s | %d | %+.2f | %+.2f | %+.2f | %+.2f | %.2f | %.2f |" %
              (["", "1", "2"][w], cl, len(cs), lag_deg(E, T, idx, step), lag_deg(M, T, idx, step), pe, pm,
               100 * er / p2p, 100 * mr / p2p))
    print("\n(a2) the same by the cycle's mean speed (fired cycles, windows pooled)")
    print("| speed (rpm) | cycles | E lag | M lag | E RMS | M RMS | gain at the output (mean |K|) |")
    print("|---|---|---|---|---|---|---|")
    bands = {}
    G = f("gain_out_nm_s2_rad2")
    for (w, cl), cs in groups.items():
        if cl in ("all", "cut"):
            continue
        for ix in cs:
            rpm = sum(float(rows[i]["speed_rpm"]) for i in ix) / len(ix)
            bands.setdefault(int(rpm // 500) * 500, []).append(ix)
    for b in sorted(bands):
        cs = bands[b]
        idx = [i for ix in cs for i in ix]
        p2p = sum(max(T[i] for i in ix) - min(T[i] for i in ix) for ix in cs) / len(cs)
        er = math.sqrt(sum((E[i] - T[i]) ** 2 for i in idx) / len(idx))
        mr = math.sqrt(sum((M[i] - T[i]) ** 2 for i in idx) / len(idx))
        print("| %d-%d | %d | %+.2f | %+.2f | %.2f | %.2f | %.3g |" %
              (b, b + 500, len(cs), lag_deg(E, T, idx, step), lag_deg(M, T, idx, step), 100 * er / p2p,
               100 * mr / p2p, sum(abs(G[i]) for i in idx) / len(idx)))
    orders = [order * m for m in (1, 2, 3, 4)]
    print("\n(c) per firing-order harmonic over the fired cycles of each window: lag (deg, + behind) and amplitude"
          "\n(%% of the truth's) of E and of M; the phase lags averaged over cycles")
    print("| window | order | E lag | M lag | E amp | M amp |")
    print("|---|---|---|---|---|---|")
    for w in (1, 2):
        cs = [ix for (ww, cl), v in groups.items() if ww == w and cl not in ("all", "cut") for ix in v]
        for o in orders if cs else []:
            le, lm, ae, am = [], [], [], []
            for ix in cs:
                ang = [float(rows[i]["angle720_deg"]) for i in ix]
                pt = phasor([T[i] for i in ix], ang, o)
                pe_, pm_ = phasor([E[i] for i in ix], ang, o), phasor([M[i] for i in ix], ang, o)
                le.append(phase_lag_deg(pe_, pt, o))
                lm.append(phase_lag_deg(pm_, pt, o))
                ae.append(abs(pe_) / abs(pt))
                am.append(abs(pm_) / abs(pt))
            mean = lambda x: sum(x) / len(x)  # noqa: E731
            print("| %d | %g | %+.2f | %+.2f | %.0f %% | %.0f %% |" %
                  (w, o, mean(le), mean(lm), 100 * mean(ae), 100 * mean(am)))
    interval = 720.0 / ncyl
    nb = 8
    width = interval / nb
    print("\n(b) by crank angle after the last firing TDC: mean E - T, M - T, X = E - M (%% of p2p), fired cycles,"
          "\nsteady against speed/MAP changing (windows pooled)")
    print("| after TDC | steady E-T | M-T | X | changing E-T | M-T | X |")
    print("|---|---|---|---|---|---|---|")
    acc = {k: [[0.0, 0.0, 0.0, 0] for _ in range(nb)] for k in ("steady", "changing")}
    p2ps = []
    for (w, cl), cs in groups.items():
        if cl in ("all", "cut"):
            continue
        key = "steady" if cl == "steady" else "changing"
        for ix in cs:
            p2ps.append(max(T[i] for i in ix) - min(T[i] for i in ix))
            for i in ix:
                rel = min((float(rows[i]["angle720_deg"]) - t) % 720.0 for t in tdcs)
                j = min(int(rel / width), nb - 1)
                b = acc[key][j]
                b[0] += E[i] - T[i]
                b[1] += M[i] - T[i]
                b[2] += E[i] - M[i]
                b[3] += 1
    p2p = sum(p2ps) / max(len(p2ps), 1)
    for j in range(nb):
        cells = []
        for k in ("steady", "changing"):
            b = acc[k][j]
            n = max(b[3], 1)
            cells += ["%+.2f" % (100 * b[m] / n / p2p) for m in range(3)]
        print("| %3.0f-%3.0f | %s |" % (j * width, (j + 1) * width, " | ".join(cells)))


if __name__ == "__main__":
    main()
