#include "load_rls.hpp"

// The load RLS's start-up tables (load_rls.hpp, rule 3): the closure coefficients, the windows' gas-work
// integrals, the in-cycle model's ripple tables, and their layout in the table cache.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "crank_kinematics.hpp"
#include "load_rls_model.hpp"

namespace torqued {

using namespace load_rls_model;  // NOLINT(google-build-using-namespace): this file's own model

namespace {
/// A window angle's pressure-model weights and dV/dθ.
struct WindowAngle {
  Weights w;
  double dvol = 0.0;
};
/// Each distinct window angle's terms, computed once: the windows repeat most angles bit for bit (22 k of the
/// demo's 38.4 k, mostly the previous firing position's window at the same shift, one cylinder on). Open
/// addressing on the angle's bits, 32 k slots (1.3 MB, untouched until used); when 3/4 full, computes
/// without keeping.
class AngleMemo {
 public:
  template <class Compute>
  WindowAngle get(double phi, Compute&& compute) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &phi, sizeof bits);
    auto i = static_cast<std::size_t>((bits * 0x9E3779B97F4A7C15ULL) >> (64 - kBits));
    for (; used_[i]; i = (i + 1) & (kSize - 1))
      if (keys_[i] == bits) return {{vals_[i].map, vals_[i].exh, vals_[i].p3}, vals_[i].dvol};
    const WindowAngle wa = compute();
    if (count_ < kSize / 4 * 3) {
      ++count_;
      used_[i] = 1;
      keys_[i] = bits;
      vals_[i] = {wa.w.map, wa.w.exh, wa.w.p3, wa.dvol};
    }
    return wa;
  }

 private:
  static constexpr int kBits = 15;
  static constexpr std::size_t kSize = std::size_t{1} << kBits;
  struct Slot {  // no initialisers: the pages stay untouched until a slot is used
    double map, exh, p3, dvol;
  };
  std::vector<std::uint8_t> used_ = std::vector<std::uint8_t>(kSize, 0);
  std::unique_ptr<std::uint64_t[]> keys_{new std::uint64_t[kSize]};
  std::unique_ptr<Slot[]> vals_{new Slot[kSize]};
  std::size_t count_ = 0;
};
}  // namespace

namespace {
/// The teeth whose period centre lies in [a, b] (relative distance from a, wrapped): the first and the last;
/// false when the window is narrower than a tooth (unusable).
bool window_teeth(const std::vector<double>& center, int samples, double a, double b, int& first, int& last) {
  first = -1;
  last = -1;
  double best_first = 1e9, best_last = -1e9;
  for (int k = 0; k < samples; ++k) {
    const double d = wrap4pi(center[static_cast<std::size_t>(k)] - a + 1e-9);  // rounding-safe edges
    if (d <= b - a + 1e-9) {
      if (d < best_first) {
        best_first = d;
        first = k;
      }
      if (d > best_last) {
        best_last = d;
        last = k;
      }
    }
  }
  return first >= 0 && last >= 0 && first != last;
}

/// A window's gas-work integrals over every cylinder q (midpoint rule at about `step`): k_map, k_exh,
/// k_p3[q], k_cc, with the pressure model at the default burn centroid (EN-9: dV_j/dθ dθ = A R f(θ − φ_j)
/// dθ).
template <class Win>
void integrate_window(Win& win, const CrankKinematics& kin, const EnergiesParams& params, int n, double v_ivc,
                      double v_c, double step, AngleMemo& memo) {
  const int steps = static_cast<int>(std::ceil(win.span / step));
  const double h = win.span / steps;
  for (int q = 0; q < n; ++q) {
    const double phase = kFourPi * q / n;
    for (int i = 0; i < steps; ++i) {
      const double th = win.c_first + (i + 0.5) * h;
      const double phi = wrap4pi(th - phase);
      const WindowAngle wa = memo.get(phi, [&] {
        const double burn = params.burn_centroid_atdc_deg * kDeg;
        const AngleTerms at =
            angle_terms_for(phi, kin, params, v_ivc, v_c, burn, 0.0, closure_kappas(params));
        return WindowAngle{model_weights(at, params, burn), at.dvol};
      });
      const Weights& w = wa.w;
      const double dv = wa.dvol * h;
      win.k_map += w.map * dv;
      win.k_exh += w.exh * dv;
      win.k_p3[static_cast<std::size_t>(q)] += w.p3 * dv;
      win.k_cc -= dv;
    }
  }
}
}  // namespace

// The closure coefficients, the windows' gas-work integrals and the ripple tables (precomputed, see the
// header's rule 3).
void LoadRls::build_tables(const CrankKinematics& kin, const std::vector<double>& center) {
  windows_tab_.clear();
  window_first_of_.assign(static_cast<std::size_t>(samples_), -1);
  window_last_of_.assign(static_cast<std::size_t>(samples_), -1);
  const double step = 0.05 * kDeg;
  build_closure(kin, step);
  build_windows(kin, center, step);
  build_ripple(center);
}

// Full-cycle ∮p dV coefficients of one cylinder (local angle), one set per burn centroid 0..kCentroids−1 deg.
// The burn-independent terms are tabulated once over the integration grid (same φ sequence for every
// centroid).
void LoadRls::build_closure(const CrankKinematics& kin, double step) {
  const EnergiesParams& params = params_;
  // Between the blowdown end and IVC only the compression before a centroid (below kCentroids − 1 degrees)
  // reads the volume powers: elsewhere there they stay 0 (dV/dθ is the same).
  std::vector<AngleTerms> grid;
  grid.reserve(static_cast<std::size_t>(kFourPi / step) + 2);
  // From max(EVO, blowdown end) model_weights() no longer reads the expansion polytrope (the configuration
  // check keeps EVO before the blowdown end; the max keeps the tables right without it).
  const double bde = std::max(params.evo_atdc_deg, params.blowdown_end_atdc_deg) * kDeg,
               ivc = (540.0 + params.ivc_abdc_deg) * kDeg;
  const double last_burn = (kCentroids - 1) * kDeg;
  for (double phi = 0.5 * step; phi < kFourPi;) {  // the same φ sequence as before (repeated addition)
    if (phi >= bde && phi < ivc && !(phi < last_burn)) {
      AngleTerms at;
      double v = 0.0;
      at.phi = phi;
      kin.volume_and_dvolume(phi, v, at.dvol);
      grid.push_back(at);
    } else {
      grid.push_back(angle_terms(phi, kin, params, v_ivc_, v_c_, closure_kappas(params)));
    }
    phi += step;
  }
  // Only the first branch of model_weights() depends on the centroid (φ < burn): the products w·dV before
  // and after the burn are formed once per angle; each centroid then adds the same products in the same
  // order as evaluating model_weights() per centroid did (identical sums, a fifth of the work).
  std::vector<std::array<double, 4>> prod(grid.size());  // before: map; after: map, exh, p3
  for (std::size_t i = 0; i < grid.size(); ++i) {
    const double dv = grid[i].dvol * step;
    const Weights before = model_weights(grid[i], params, kFourPi);
    const Weights after = model_weights(grid[i], params, -1.0);
    prod[i] = {before.map * dv, after.map * dv, after.exh * dv, after.p3 * dv};
  }
  // The grid's φ increase, so "before the burn" is a prefix [0, ib): each sum runs over the prefix, then over
  // the rest, in the same order and with the same terms as one loop choosing per angle (no choice per angle).
  // The p_exh closure is the last centroid's (as the per-centroid loop left it): summed for that one only.
  // The prefix's p3 and p_exh terms are ±0 (+0 summed); its MAP sum is the running prefix sum, carried from
  // one centroid to the next (the same additions in the same order).
  std::vector<std::size_t> ib(kCentroids);
  std::vector<double> pre(kCentroids);
  std::size_t i0 = 0;
  double prefix = 0.0;
  for (int ci = 0; ci < kCentroids; ++ci) {
    const double burn = ci * kDeg;
    for (; i0 < grid.size() && grid[i0].phi < burn; ++i0) prefix += prod[i0][0];  // burn grows with ci
    ib[static_cast<std::size_t>(ci)] = i0;
    pre[static_cast<std::size_t>(ci)] = prefix;
  }
  closure_sums(prod, ib, pre, cyc_map_.data(), cyc_p3_.data());
  cyc_exh_ = 0.0;
  for (std::size_t i = i0; i < grid.size(); ++i) cyc_exh_ += prod[i][2];
}

// One window per firing position and shift (its teeth, inertias and gas-work integrals), then each position's
// closing window: the smallest shift kept (it ends at window_end_btdc, the latest).
void LoadRls::build_windows(const CrankKinematics& kin, const std::vector<double>& center, double step) {
  const EnergiesParams& params = params_;
  const int n = engine_.cylinders;
  const double pitch = kFourPi / samples_;
  AngleMemo memo;
  for (int m = 0; m < n; ++m)
    for (int shift = 0; shift < std::max(1, params.rls_window_shifts); ++shift) {
      const double tdc = kFourPi * m / n - shift * pitch;
      const double a = tdc - params.window_start_btdc_deg * kDeg;
      const double b = tdc - params.window_end_btdc_deg * kDeg;
      int first = -1, last = -1;
      if (!window_teeth(center, samples_, a, b, first, last)) continue;
      if (window_first_of_[static_cast<std::size_t>(first)] >= 0 ||
          window_last_of_[static_cast<std::size_t>(last)] >= 0) {
        continue;  // irregular wheel: two shifts mapped onto the same teeth
      }
      Window win;
      win.first = first;
      win.last = last;
      win.c_first = center[static_cast<std::size_t>(first)];
      win.c_last = center[static_cast<std::size_t>(last)];
      win.span = wrap4pi(win.c_last - win.c_first);
      win.j_first = kin.inertia(win.c_first);
      win.j_last = kin.inertia(win.c_last);
      integrate_window(win, kin, params, n, v_ivc_, v_c_, step, memo);
      window_first_of_[static_cast<std::size_t>(first)] = static_cast<int>(windows_tab_.size());
      window_last_of_[static_cast<std::size_t>(last)] = static_cast<int>(windows_tab_.size());
      win.position = m;
      windows_tab_.push_back(win);
    }
  for (int m = 0; m < n; ++m) {
    for (std::size_t w = 0; w < windows_tab_.size(); ++w) {
      if (windows_tab_[w].position == m) {
        windows_tab_[w].closes_group = true;
        break;  // pushed in shift order: the first one of a position has the smallest shift
      }
    }
  }
}

// The tables as one array of doubles for the table cache (integers are exact in a double): the closure
// coefficients, the ripple tables built (ripple_first..last), then each window; per cylinder only the
// engine's (the key holds the engine, the table range and the layout's version).
namespace {
constexpr std::size_t kWindowFields = 13;  // and one k_p3 per cylinder
}  // namespace

void LoadRls::pack_tables(std::vector<double>& t) const {
  const auto ks = static_cast<std::size_t>(samples_);
  const auto n = static_cast<std::size_t>(engine_.cylinders);
  const auto lo = static_cast<std::size_t>(rip_lo_), hi = static_cast<std::size_t>(rip_hi_) + 1;
  auto rows = [&](const std::vector<double>& v, std::size_t stride, std::size_t used) {
    for (std::size_t r = lo * ks; r < hi * ks; ++r)
      t.insert(t.end(), v.begin() + static_cast<std::ptrdiff_t>(r * stride),
               v.begin() + static_cast<std::ptrdiff_t>(r * stride + used));
  };
  t.clear();
  t.push_back(static_cast<double>(windows_tab_.size()));
  t.insert(t.end(), cyc_map_.begin(), cyc_map_.end());
  t.insert(t.end(), cyc_p3_.begin(), cyc_p3_.end());
  t.push_back(cyc_exh_);
  for (const auto* c : {&rip_cm_, &rip_cp_, &rip_ce_})
    t.insert(t.end(), c->begin() + rip_lo_, c->begin() + rip_hi_ + 1);
  rows(rip_map_, 1, 1);
  rows(rip_const_, 1, 1);
  rows(rip_p3_, kMaxCylinders, n);
  for (int k = 0; k < samples_; ++k) {
    t.push_back(window_first_of_[static_cast<std::size_t>(k)]);
    t.push_back(window_last_of_[static_cast<std::size_t>(k)]);
  }
  for (const Window& w : windows_tab_) {
    t.insert(t.end(), {static_cast<double>(w.first), static_cast<double>(w.last), w.c_first, w.c_last, w.span,
                       w.j_first, w.j_last, w.k_map, w.k_exh, w.k_cc, static_cast<double>(w.position),
                       w.closes_group ? 1.0 : 0.0});
    t.insert(t.end(), w.k_p3.begin(), w.k_p3.begin() + static_cast<std::ptrdiff_t>(n));
    t.push_back(0.0);  // spare
  }
}

bool LoadRls::unpack_tables(const std::vector<double>& t) {
  const auto ks = static_cast<std::size_t>(samples_);
  const auto n = static_cast<std::size_t>(engine_.cylinders);
  constexpr auto kt = static_cast<std::size_t>(kRippleTables);
  const auto lo = static_cast<std::size_t>(rip_lo_), nt = static_cast<std::size_t>(rip_hi_ - rip_lo_ + 1);
  const std::size_t head = 1 + 2 * kCentroids + 1 + 3 * nt + nt * ks * (2 + n) + 2 * ks;
  if (t.size() < head) return false;
  const double nw = t[0];
  if (!(nw >= 0.0) || t.size() != head + static_cast<std::size_t>(nw) * (kWindowFields + n)) return false;
  auto it = t.begin() + 1;
  auto take = [&it](auto first, std::size_t count) {
    std::copy(it, it + static_cast<std::ptrdiff_t>(count), first);
    it += static_cast<std::ptrdiff_t>(count);
  };
  take(cyc_map_.begin(), cyc_map_.size());
  take(cyc_p3_.begin(), cyc_p3_.size());
  cyc_exh_ = *it++;
  rip_cm_.fill(0.0);
  rip_cp_.fill(0.0);
  rip_ce_.fill(0.0);
  for (auto* c : {&rip_cm_, &rip_cp_, &rip_ce_}) take(c->begin() + rip_lo_, nt);
  rip_map_.assign(kt * ks, 0.0);
  rip_const_.assign(kt * ks, 0.0);
  rip_p3_.assign(kt * ks * kMaxCylinders, 0.0);
  take(rip_map_.begin() + static_cast<std::ptrdiff_t>(lo * ks), nt * ks);
  take(rip_const_.begin() + static_cast<std::ptrdiff_t>(lo * ks), nt * ks);
  for (std::size_t r = lo * ks; r < (lo + nt) * ks; ++r)
    take(rip_p3_.begin() + static_cast<std::ptrdiff_t>(r * kMaxCylinders), n);
  window_first_of_.resize(ks);
  window_last_of_.resize(ks);
  for (std::size_t k = 0; k < ks; ++k) {
    window_first_of_[k] = static_cast<int>(*it++);
    window_last_of_[k] = static_cast<int>(*it++);
  }
  windows_tab_.assign(static_cast<std::size_t>(nw), Window{});
  for (Window& w : windows_tab_) {
    w.first = static_cast<int>(it[0]);
    w.last = static_cast<int>(it[1]);
    w.c_first = it[2];
    w.c_last = it[3];
    w.span = it[4];
    w.j_first = it[5];
    w.j_last = it[6];
    w.k_map = it[7];
    w.k_exh = it[8];
    w.k_cc = it[9];
    w.position = static_cast<int>(it[10]);
    w.closes_group = it[11] != 0.0;
    std::copy(it + 12, it + 12 + static_cast<std::ptrdiff_t>(n), w.k_p3.begin());
    it += static_cast<std::ptrdiff_t>(kWindowFields + n);
  }
  return true;
}

// Per-sample gas-torque ripple tables: the pressure model's work over [c_k, c_{k+1}] per unit of
// each input, divided by the step, minus the 720° mean (the mean indicated torque is the cycle balance's, not
// this).
void LoadRls::build_ripple(const std::vector<double>& center) {
  const auto ks = static_cast<std::size_t>(samples_);
  constexpr auto kt = static_cast<std::size_t>(kRippleTables);
  rip_map_.assign(kt * ks, 0.0);
  rip_const_.assign(kt * ks, 0.0);
  rip_p3_.assign(kt * ks * kMaxCylinders, 0.0);
  rip_cm_.fill(0.0);
  rip_cp_.fill(0.0);
  rip_ce_.fill(0.0);
  RippleBuild b;
  b.dur = params_.burn_duration_deg * kDeg;
  b.full_below = -std::numeric_limits<double>::infinity();
  b.s_lo = std::numeric_limits<double>::infinity();
  b.s_hi = -b.s_lo;
  for (int t = rip_lo_; t <= rip_hi_; ++t) {
    const auto ti = static_cast<std::size_t>(t);
    b.burn[ti] = (params_.burn_centroid_atdc_deg + (t - kRippleBase) * kRippleStepDeg) * kDeg;
    b.start[ti] = burn_start(b.burn[ti], b.dur, params_);
    b.full_below = std::max(b.full_below, b.burn[ti]);
    if (b.dur > 0.0) {
      b.s_lo = std::min(b.s_lo, b.start[ti]);
      b.s_hi = std::max(b.s_hi, b.start[ti] + b.dur);
    }
  }
  build_ripple_closure(b);
  build_ripple_samples(center, b);
}

namespace {
/// The powers the tables built read at φ (Powers; RippleBuild::full_below, s_lo, s_hi: conservative at the
/// ends).
/// Every table built takes the weights after its burn at φ: past every centroid, outside every burn.
bool all_after(double phi, double full_below, double s_lo, double s_hi) noexcept {
  const double s = phi > kTwoPi ? phi - kFourPi : phi;
  return !(phi < full_below || (s >= s_lo && s <= s_hi));
}
Powers reads(double phi, const EnergiesParams& prm, double full_below, double s_lo, double s_hi) noexcept {
  if (!all_after(phi, full_below, s_lo, s_hi)) return {};
  return {phi >= (540.0 + prm.ivc_abdc_deg) * kDeg,
          phi < std::max(prm.evo_atdc_deg, prm.blowdown_end_atdc_deg) * kDeg};
}
}  // namespace

// Full-cycle closure of the ripple model for one cylinder (ripple_p3), every table built: ∮p dV per Pa of MAP
// and of p3, and the p_exh part (J). Each angle's burn-independent terms are computed once for all tables.
void LoadRls::build_ripple_closure(const RippleBuild& b) {
  const CrankKinematics kin(engine_);
  const Kappas kap = ripple_kappas(params_);
  std::array<double, kRippleTables> cm{}, cp{}, ce{};
  const auto lo = static_cast<std::size_t>(rip_lo_), hi = static_cast<std::size_t>(rip_hi_);
  constexpr int kClosureSteps = 720 * 4;  // 0.25° steps over the cycle
  for (int i = 0; i < kClosureSteps; ++i) {
    const double phi = (i + 0.5) * kFourPi / kClosureSteps;
    const SharedAngle sa =
        shared_angle(phi, kin, params_, v_ivc_, v_c_, kap, reads(phi, params_, b.full_below, b.s_lo, b.s_hi));
    const double dv = sa.dvol * kFourPi / kClosureSteps;
    if (all_after(phi, b.full_below, b.s_lo, b.s_hi)) {  // the same terms for every table (vectorised)
      const double m = sa.after.map * dv, p = sa.after.p3 * dv,
                   e = sa.after.exh * params_.exhaust_pressure_pa * dv;
      for (std::size_t t = lo; t <= hi; ++t) {
        cm[t] += m;
        cp[t] += p;
        ce[t] += e;
      }
      continue;
    }
    for (std::size_t t = lo; t <= hi; ++t) {
      const Weights w = table_weights(sa, params_, b.burn[t], b.start[t], b.dur);
      cm[t] += w.map * dv;
      cp[t] += w.p3 * dv;
      ce[t] += w.exh * params_.exhaust_pressure_pa * dv;
    }
  }
  rip_cm_ = cm;
  rip_cp_ = cp;
  rip_ce_ = ce;
}

namespace {
/// One sample's integration angles: per cylinder range, the extent of φ and of s (φ − 4π beyond 2π).
struct SampleAngles {
  std::vector<SharedAngle> at;  ///< [q * steps + i]
  std::array<double, kMaxCylinders> phi_min{}, phi_max{}, s_min{}, s_max{};
};
/// A table's weights over one cylinder's range of a sample: all before its centroid (0), all after (1), or
/// mixed / in the burn (−1). Tables whose classes agree on every range read the same weights at every angle.
int range_class(const SampleAngles& sa, int q, double burn, double a0, double dur) noexcept {
  const auto qi = static_cast<std::size_t>(q);
  if (dur > 0.0 && !(sa.s_max[qi] <= a0 || sa.s_min[qi] >= a0 + dur)) return -1;  // table_weights' burn test
  if (sa.phi_max[qi] < burn) return 0;
  return sa.phi_min[qi] >= burn ? 1 : -1;
}
/// What shared_angle() takes, and RippleBuild's full_below, s_lo, s_hi.
struct AngleInputs {
  const CrankKinematics& kin;
  const EnergiesParams& prm;
  double v_ivc, v_c;
  Kappas kap;
  double full_below, s_lo, s_hi;
};
/// The angles of sample [c0, c0 + steps·h] for every cylinder, in the order they are summed.
void sample_angles(SampleAngles& sa, double c0, double h, int steps, int n, const AngleInputs& in) {
  sa.at.clear();
  for (int q = 0; q < n; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    sa.phi_min[qi] = sa.s_min[qi] = std::numeric_limits<double>::infinity();
    sa.phi_max[qi] = sa.s_max[qi] = -std::numeric_limits<double>::infinity();
    for (int i = 0; i < steps; ++i) {
      const double phi = wrap4pi(c0 + (i + 0.5) * h - kFourPi * q / n);
      const double s = phi > kTwoPi ? phi - kFourPi : phi;
      sa.phi_min[qi] = std::min(sa.phi_min[qi], phi);
      sa.phi_max[qi] = std::max(sa.phi_max[qi], phi);
      sa.s_min[qi] = std::min(sa.s_min[qi], s);
      sa.s_max[qi] = std::max(sa.s_max[qi], s);
      sa.at.push_back(shared_angle(phi, in.kin, in.prm, in.v_ivc, in.v_c, in.kap,
                                   reads(phi, in.prm, in.full_below, in.s_lo, in.s_hi)));
    }
  }
}
}  // namespace

// Per-sample gas-torque ripple of every table built: the pressure model's work over [c_k, c_{k+1}] per unit
// of each input, divided by the step, minus the 720° mean (the mean indicated torque is the cycle balance's,
// not this). A table whose weights over the sample are another's (the same side of their centroids on every
// cylinder's range, no burn) gets that one's sums: the same terms added in the same order.
void LoadRls::build_ripple_samples(const std::vector<double>& center, const RippleBuild& b) {
  const CrankKinematics kin(engine_);
  const Kappas kap = ripple_kappas(params_);
  const int n = engine_.cylinders;
  const auto ks = static_cast<std::size_t>(samples_);
  constexpr std::size_t kt = kRippleTables;
  const auto lo = static_cast<std::size_t>(rip_lo_), hi = static_cast<std::size_t>(rip_hi_);
  std::array<double, kt> wm{}, wc{};
  std::array<std::array<double, kMaxCylinders>, kt> wp{};
  SampleAngles sa;
  const AngleInputs in{kin, params_, v_ivc_, v_c_, kap, b.full_below, b.s_lo, b.s_hi};
  for (int k = 0; k < samples_; ++k) {
    const double c0 = center[static_cast<std::size_t>(k)];
    const double span = wrap4pi(center[static_cast<std::size_t>((k + 1) % samples_)] - c0);
    const int steps = std::max(4, static_cast<int>(std::ceil(span / (0.25 * kDeg))));
    const double h = span / steps;
    sample_angles(sa, c0, h, steps, n, in);
    std::array<double, kt> tm{}, tc{};
    std::array<std::array<double, kMaxCylinders>, kt> tp{};
    std::array<std::uint32_t, kt> code{};  // per table: its classes, 2 bits per cylinder; 0: computed alone
    for (std::size_t t = lo; t <= hi; ++t) {
      std::uint32_t c = 1;
      std::array<int, kMaxCylinders> cls{};
      for (int q = 0; q < n; ++q) {
        const int cl = range_class(sa, q, b.burn[t], b.start[t], b.dur);
        cls[static_cast<std::size_t>(q)] = cl;
        c = cl < 0 || c == 0 ? 0 : (c << 2) | static_cast<std::uint32_t>(cl);
      }
      code[t] = c;
      std::size_t same = t;
      if (c != 0)
        for (std::size_t u = lo; u < t && same == t; ++u)
          if (code[u] == c) same = u;
      if (same != t) {
        tm[t] = tm[same];
        tc[t] = tc[same];
        tp[t] = tp[same];
        continue;
      }
      for (int q = 0; q < n; ++q) {
        const int cl = cls[static_cast<std::size_t>(q)];  // a clean range: table_weights' branch is known
        for (int i = 0; i < steps; ++i) {
          const SharedAngle& a = sa.at[static_cast<std::size_t>(q * steps + i)];
          const double dv = a.dvol * h;
          const Weights w = cl == 0   ? a.before
                            : cl == 1 ? a.after
                                      : table_weights(a, params_, b.burn[t], b.start[t], b.dur);
          tm[t] += w.map * dv;
          tc[t] += (w.exh * params_.exhaust_pressure_pa - engine_.crankcase_pressure_pa) * dv;
          tp[t][static_cast<std::size_t>(q)] += w.p3 * dv;
        }
      }
    }
    const auto kk = static_cast<std::size_t>(k);
    for (std::size_t t = lo; t <= hi; ++t) {
      rip_map_[t * ks + kk] = tm[t] / span;
      rip_const_[t * ks + kk] = tc[t] / span;
      for (int q = 0; q < n; ++q)
        rip_p3_[(t * ks + kk) * kMaxCylinders + static_cast<std::size_t>(q)] =
            tp[t][static_cast<std::size_t>(q)] / span;
      wm[t] += tm[t];
      wc[t] += tc[t];
      for (int q = 0; q < n; ++q) wp[t][static_cast<std::size_t>(q)] += tp[t][static_cast<std::size_t>(q)];
    }
  }
  for (std::size_t t = lo; t <= hi; ++t) {
    for (std::size_t k = 0; k < ks; ++k) {
      rip_map_[t * ks + k] -= wm[t] / kFourPi;
      rip_const_[t * ks + k] -= wc[t] / kFourPi;
      for (int q = 0; q < n; ++q)
        rip_p3_[(t * ks + k) * kMaxCylinders + static_cast<std::size_t>(q)] -=
            wp[t][static_cast<std::size_t>(q)] / kFourPi;
    }
  }
}
}  // namespace torqued
