#pragma once
// Analytic crank-speed generator for the angle-estimator tests (helper "angle"): integrates the energy form
// of the crankshaft balance d(½J(θ)θ̇²)/dθ = T_ind(θ) − T_load (docs/equations.md §0, CF-2) for a known,
// speed-independent indicated torque, so the truth is exact. Tooth edges get a fixed per-tooth angle error
// and Gaussian jitter. Also: the accuracy metrics shared by the tests (RMS error in % of the true
// peak-to-peak, lag by cross-correlation).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "crank_kinematics.hpp"
#include "engine_geometry.hpp"
#include "samples.hpp"
#include "tooth_preprocessor.hpp"

namespace torqued::test {

struct SyntheticRun {
  std::vector<ToothSample> samples;    ///< measured teeth (nominal widths), first one not synced
  std::vector<double> t_ind_nm;        ///< true indicated torque at each sample's edge
  std::vector<double> t_net_nm;        ///< true T_ind − T_load at each edge
  std::vector<double> edge_error_rad;  ///< per physical tooth machining error (rad)
  double load_nm = 0.0;                ///< constant load (= cycle-mean indicated torque)
};

struct SyntheticSpec {
  EngineGeometry engine{};
  WheelGeometry wheel{};
  double rpm = 2000.0;  ///< mean speed
  int cycles = 30;
  double peak_bar = 40.0;       ///< combustion pressure bump (bar) on top of the motored pressure
  double map_bar = 0.6;         ///< pressure at IVC (bar)
  double burn_peak_rad = 0.35;  ///< crank angle of the combustion bump's peak after firing TDC (rad)
  double tooth_error_deg = 0.05;
  double jitter_s = 0.3e-6;
  std::uint64_t wheel_seed = 7;  ///< fixed wheel (same machining errors for every run with this seed)
  std::uint64_t noise_seed = 11;
};

/// Gaussian from mt19937_64 with our own Box-Muller (independent of the library's distributions).
class Gauss {
 public:
  explicit Gauss(std::uint64_t seed) : rng_(seed) {}
  double operator()() {
    const double u1 = (static_cast<double>(rng_() >> 11) + 0.5) * 0x1.0p-53;
    const double u2 = (static_cast<double>(rng_() >> 11) + 0.5) * 0x1.0p-53;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  std::mt19937_64 rng_;
};

/// Indicated torque of the synthetic engine at angle θ after cylinder 1's firing TDC: motored polytropic
/// pressure (κ = 1.3 from IVC at BDC) plus a Gaussian combustion bump (20° after TDC unless
/// SyntheticSpec::burn_peak_rad says otherwise).
inline double synthetic_t_ind(const CrankKinematics& kin, const SyntheticSpec& sp, double theta) {
  const double pi = std::numbers::pi;
  double sum = 0.0;
  for (int c = 1; c <= sp.engine.cylinders; ++c) {
    double a = std::fmod(theta - kin.phase(c), 4.0 * pi);
    if (a < 0) a += 4.0 * pi;
    if (a >= 3.0 * pi) a -= 4.0 * pi;  // local angle in [−π, 3π): compression (−π,0), expansion (0,π)
    double p = sp.map_bar * 1e5;
    if (a > -pi && a < pi) {
      p = sp.map_bar * 1e5 * std::pow(kin.volume(pi) / kin.volume(a), 1.3);
      const double d = (a - sp.burn_peak_rad) / 0.30;
      p += sp.peak_bar * 1e5 * std::exp(-d * d) * (a > 0 ? 1.0 : std::exp(-d * d));
    }
    sum += kin.gas_torque(theta, c, p);
  }
  return sum;
}

inline SyntheticRun make_synthetic(const SyntheticSpec& sp) {
  const double pi = std::numbers::pi;
  const CrankKinematics kin(sp.engine);
  const int fine = 14400;  // 0.05° steps per 720°
  const double h = 4.0 * pi / fine;
  // cycle-mean indicated torque → constant load (steady state)
  std::vector<double> tq(static_cast<std::size_t>(fine) + 1);
  double mean = 0.0;
  for (int i = 0; i <= fine; ++i) {
    tq[static_cast<std::size_t>(i)] = synthetic_t_ind(kin, sp, i * h);
    if (i < fine) mean += tq[static_cast<std::size_t>(i)] / fine;
  }
  SyntheticRun run;
  run.load_nm = mean;
  // E(θ) by trapezoid of T_net (the trapezoid error is O(h²) and identical for every cycle), θ̇ = sqrt(2E/J).
  const double omega0 = sp.rpm * pi / 30.0;
  std::vector<double> energy(static_cast<std::size_t>(fine) + 1), speed(energy.size()), time(energy.size());
  energy[0] = 0.5 * kin.inertia(0.0) * omega0 * omega0;
  for (int i = 1; i <= fine; ++i) {
    const auto u = static_cast<std::size_t>(i);
    energy[u] = energy[u - 1] + 0.5 * h * (tq[u - 1] + tq[u] - 2.0 * mean);
  }
  for (int i = 0; i <= fine; ++i) {
    const auto u = static_cast<std::size_t>(i);
    speed[u] = std::sqrt(2.0 * energy[u] / kin.inertia(i * h));
  }
  time[0] = 0.0;
  for (int i = 1; i <= fine; ++i) {
    const auto u = static_cast<std::size_t>(i);
    time[u] = time[u - 1] + 0.5 * h * (1.0 / speed[u - 1] + 1.0 / speed[u]);
  }
  const double cycle_s = time[static_cast<std::size_t>(fine)];
  // t(θ) within a cycle by cubic Hermite with dt/dθ = 1/θ̇ at the grid points.
  auto time_at = [&](double theta) {
    const double cyc = std::floor(theta / (4.0 * pi));
    double th = theta - cyc * 4.0 * pi;
    int i = std::min(fine - 1, static_cast<int>(th / h));
    const double s = (th - i * h) / h;
    const auto u = static_cast<std::size_t>(i);
    const double t0 = time[u], t1 = time[u + 1], m0 = h / speed[u], m1 = h / speed[u + 1];
    const double s2 = s * s, s3 = s2 * s;
    return cyc * cycle_s + (2 * s3 - 3 * s2 + 1) * t0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * t1 +
           (s3 - s2) * m1;
  };
  std::vector<double> e1, w1;
  ToothAngleTable::wheel_edges(sp.wheel, e1, w1);
  const int teeth = static_cast<int>(e1.size());
  Gauss wheel_rng(sp.wheel_seed), noise(sp.noise_seed);
  run.edge_error_rad.resize(static_cast<std::size_t>(teeth));
  for (auto& e : run.edge_error_rad) e = sp.tooth_error_deg * pi / 180.0 * wheel_rng();
  const int kk = 2 * teeth;
  std::int64_t prev_ns = 0;
  for (int n = 0; n < sp.cycles * kk + 1; ++n) {
    const int k = n % kk;
    const int p = k % teeth;
    const double wheel_angle = (n / kk) * 4.0 * pi + (k / teeth) * 2.0 * pi +
                               e1[static_cast<std::size_t>(p)] +
                               run.edge_error_rad[static_cast<std::size_t>(p)];
    const double theta = wheel_angle - sp.engine.tdc_offset_rad;
    const double t =
        time_at(theta + 4.0 * pi) - cycle_s + sp.jitter_s * noise();  // keep the argument positive
    const auto t_ns = static_cast<std::int64_t>(std::llround((t + 1.0) * 1e9));
    ToothSample s;
    s.t_ns = t_ns;
    s.tooth = k;
    s.angle_rad = (k / teeth) * 2.0 * pi + e1[static_cast<std::size_t>(p)];
    s.width_rad = w1[static_cast<std::size_t>(p)];
    s.dt_s = n == 0 ? 0.0 : 1e-9 * static_cast<double>(t_ns - prev_ns);
    s.synced = n > 0;
    prev_ns = t_ns;
    const double ti = synthetic_t_ind(kin, sp, theta);
    run.samples.push_back(s);
    run.t_ind_nm.push_back(ti);
    run.t_net_nm.push_back(ti - mean);
  }
  return run;
}

/// In-cycle accuracy of an estimate series against truth (same indices = same edge).
struct Accuracy {
  double rms_pct_p2p = 0.0;  ///< RMS(est − truth) / (max − min of truth) × 100
  double lag_deg = 0.0;      ///< shift of the estimate behind truth maximising the cross-correlation (deg)
  double rms_nm = 0.0;
  double p2p_nm = 0.0;
};

/// `step_deg` is the tooth pitch; lag resolved to a fraction of a tooth by parabolic interpolation.
inline Accuracy accuracy(const std::vector<double>& est, const std::vector<double>& truth, double step_deg) {
  Accuracy a;
  const std::size_t n = std::min(est.size(), truth.size());
  if (n < 50) return a;
  double mn = truth[0], mx = truth[0], se = 0.0, me = 0.0, mt = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mn = std::min(mn, truth[i]);
    mx = std::max(mx, truth[i]);
    se += (est[i] - truth[i]) * (est[i] - truth[i]);
    me += est[i] / n;
    mt += truth[i] / n;
  }
  a.rms_nm = std::sqrt(se / n);
  a.p2p_nm = mx - mn;
  a.rms_pct_p2p = 100.0 * a.rms_nm / a.p2p_nm;
  const int max_shift = 12;
  std::vector<double> cc(2 * max_shift + 1);
  for (int s = -max_shift; s <= max_shift; ++s) {
    double acc = 0.0;
    for (std::size_t i = max_shift; i + max_shift < n; ++i)
      acc += (est[i] - me) * (truth[static_cast<std::size_t>(static_cast<long>(i) - s)] - mt);
    cc[static_cast<std::size_t>(s + max_shift)] = acc;
  }
  const auto best = std::max_element(cc.begin(), cc.end()) - cc.begin();
  double frac = 0.0;
  if (best > 0 && best < static_cast<long>(cc.size()) - 1) {
    const double y0 = cc[static_cast<std::size_t>(best - 1)], y1 = cc[static_cast<std::size_t>(best)],
                 y2 = cc[static_cast<std::size_t>(best + 1)];
    const double den = y0 - 2 * y1 + y2;
    if (den != 0.0) frac = 0.5 * (y0 - y2) / den;
  }
  a.lag_deg = (static_cast<double>(best - max_shift) + frac) * step_deg;
  return a;
}

}  // namespace torqued::test
