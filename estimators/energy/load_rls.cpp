#include "load_rls.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "crank_kinematics.hpp"
#include "cycle_energy.hpp"
#include "table_cache.hpp"

namespace torqued {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * kPi;
constexpr double kFourPi = 4.0 * kPi;
constexpr double kDeg = kPi / 180.0;
double wrap4pi(double a) noexcept {
  a = std::fmod(a, kFourPi);
  return a < 0.0 ? a + kFourPi : a;
}

/// Burn-independent pieces of the pressure model at local angle φ (volume powers, blowdown blend, dV/dθ):
/// evaluated once per integration angle and shared by every burn centroid (no trigonometry/pow in the inner
/// loops).
struct AngleTerms {
  double phi = 0.0;
  double dvol = 0.0;      ///< dV/dθ (m³/rad)
  double ivc_poly = 0.0;  ///< (V_IVC/V)^κ
  double c_poly = 0.0;    ///< (V_c/V)^κ
  double blend = 0.0;     ///< raised-cosine blowdown blend (only meaningful in [EVO, blowdown end))
};
/// Polytropic exponents of the compression (from IVC) and expansion (from the burn centroid) polytropes.
struct Kappas {
  double comp = 1.3, exp = 1.3;
};
Kappas closure_kappas(const EnergiesParams& prm) noexcept {
  return {prm.polytropic_kappa, prm.polytropic_kappa};
}
/// The in-cycle gas torque model's exponents: energies.incycle_*_kappa, 0 = energies.polytropic_kappa.
Kappas ripple_kappas(const EnergiesParams& prm) noexcept {
  return {prm.incycle_compression_kappa > 0.0 ? prm.incycle_compression_kappa : prm.polytropic_kappa,
          prm.incycle_expansion_kappa > 0.0 ? prm.incycle_expansion_kappa : prm.polytropic_kappa};
}
AngleTerms angle_terms(double phi, const CrankKinematics& kin, const EnergiesParams& prm, double v_ivc,
                       double v_c, Kappas kap) noexcept {
  const double evo = prm.evo_atdc_deg * kDeg;
  const double bde = prm.blowdown_end_atdc_deg * kDeg;
  double v = 0.0;
  AngleTerms t;
  t.phi = phi;
  kin.volume_and_dvolume(phi, v, t.dvol);
  t.ivc_poly = std::pow(v_ivc / v, kap.comp);
  t.c_poly = std::pow(v_c / v, kap.exp);
  t.blend = (phi >= evo && phi < bde) ? 0.5 * (1.0 + std::cos(kPi * (phi - evo) / (bde - evo))) : 0.0;
  return t;
}

/// Start of the in-cycle model's burn of duration `dur` whose 50 % burned point is `burn` (rad): half the
/// duration before it for the raised cosine; for the Wiebe function x_b = 1 − exp(−a u^(m+1)) (Heywood
/// §9.2.1, eq. (9.23)) the 50 % point is at u50 = (ln 2 / a)^(1/(m+1)) of the duration.
double burn_start(double burn, double dur, const EnergiesParams& prm) noexcept {
  if (prm.burn_wiebe_a <= 0.0) return burn - 0.5 * dur;
  return burn - dur * std::pow(std::numbers::ln2 / prm.burn_wiebe_a, 1.0 / (prm.burn_wiebe_m + 1.0));
}
/// Burned fraction `x` into a burn of duration `dur`: raised cosine, or the Wiebe function scaled to reach 1
/// at its end.
double burned_fraction(double x, double dur, const EnergiesParams& prm) noexcept {
  if (prm.burn_wiebe_a <= 0.0) return 0.5 * (1.0 - std::cos(kPi * x / dur));
  const double a = prm.burn_wiebe_a;
  return (1.0 - std::exp(-a * std::pow(x / dur, prm.burn_wiebe_m + 1.0))) / (1.0 - std::exp(-a));
}
/// angle_terms() with only the volume powers that model_weights(·, burn) (dur = 0) or the in-cycle model's
/// weights (dur > 0, table_weights) read at φ (the others stay 0): the same values where used, at half the
/// pow() calls.
AngleTerms angle_terms_for(double phi, const CrankKinematics& kin, const EnergiesParams& prm, double v_ivc,
                           double v_c, double burn, double dur, Kappas kap) noexcept {
  const double bde = prm.blowdown_end_atdc_deg * kDeg;
  const double ivc = (540.0 + prm.ivc_abdc_deg) * kDeg;
  bool need_ivc = phi < burn || phi >= ivc;
  bool need_c = phi >= burn && phi < bde;
  if (dur > 0.0) {
    const double s = phi > kTwoPi ? phi - kFourPi : phi;
    const double a0 = burn_start(burn, dur, prm);
    if (s > a0 && s < a0 + dur) need_ivc = need_c = true;
  }
  if (need_ivc && need_c) return angle_terms(phi, kin, prm, v_ivc, v_c, kap);
  const double evo = prm.evo_atdc_deg * kDeg;
  AngleTerms t;
  t.phi = phi;
  if (need_ivc || need_c) {
    double v = 0.0;
    kin.volume_and_dvolume(phi, v, t.dvol);
    if (need_ivc) t.ivc_poly = std::pow(v_ivc / v, kap.comp);
    if (need_c) t.c_poly = std::pow(v_c / v, kap.exp);
  } else {
    t.dvol = kin.dvolume(phi);
  }
  t.blend = (phi >= evo && phi < bde) ? 0.5 * (1.0 + std::cos(kPi * (phi - evo) / (bde - evo))) : 0.0;
  return t;
}

/// Pressure-model weights at local angle φ after a cylinder's firing TDC: p = w_map·MAP + w_exh·p_exh +
/// w_p3·p3.
struct Weights {
  double map = 0.0, exh = 0.0, p3 = 0.0;
};
Weights model_weights(const AngleTerms& t, const EnergiesParams& prm, double burn_rad) noexcept {
  const double phi = t.phi;
  const double evo = prm.evo_atdc_deg * kDeg;
  const double bde = prm.blowdown_end_atdc_deg * kDeg;
  const double ivc = (540.0 + prm.ivc_abdc_deg) * kDeg;
  const double burn = burn_rad;
  Weights w;
  if (phi < burn) {
    // Before the burn centroid the charge follows the compression polytrope back out (heat release lumped at
    // the centroid: a constant-volume burn at TDC would understate the late expansion pressure for a given
    // work).
    w.map = prm.ivc_pressure_factor * t.ivc_poly;
  } else if (phi < evo) {
    w.p3 = t.c_poly;
  } else if (phi < bde) {
    // Blowdown: raised-cosine blend from the polytrope to p_exh between EVO and the blowdown end.
    const double c = t.blend;
    w.p3 = c * t.c_poly;
    w.exh = 1.0 - c;
  } else if (phi < kTwoPi) {
    w.exh = 1.0;
  } else if (phi < ivc) {
    w.map = 1.0;
  } else {
    w.map = prm.ivc_pressure_factor * t.ivc_poly;
  }
  return w;
}

/// The in-cycle gas torque model's weights are model_weights() with the heat release spread over `dur` around
/// the centroid by a raised-cosine burned fraction x_b, p = (1 − x_b)·compression + x_b·expansion polytrope.
/// The lumped burn's pressure step is harmless in a window integral but is a torque step in the in-cycle
/// shape, which the Kalman's smooth coloured-noise prior cannot correct.
/// What one integration angle contributes to every ripple table is computed once for all of them
/// (build_ripple): the volume powers, dV/dφ as angle_terms_for() takes it (the plain dV/dφ from the blowdown
/// end to IVC, where neither polytrope is read), and model_weights() before the burn centroid (compression)
/// and after it (its other branches). The weights depend on the burn only through which branch holds and,
/// inside the burn, the burned fraction, so table_weights() gives one table's weights exactly.
struct SharedAngle {
  AngleTerms full;
  Weights before, after;
  double dvol = 0.0;
};
SharedAngle shared_angle(double phi, const CrankKinematics& kin, const EnergiesParams& prm, double v_ivc,
                         double v_c, Kappas kap) noexcept {
  SharedAngle a;
  a.full = angle_terms(phi, kin, prm, v_ivc, v_c, kap);
  const double bde = prm.blowdown_end_atdc_deg * kDeg;
  const double ivc = (540.0 + prm.ivc_abdc_deg) * kDeg;
  a.dvol = phi >= bde && phi < ivc ? kin.dvolume(phi) : a.full.dvol;
  a.before = model_weights(a.full, prm, std::numeric_limits<double>::infinity());
  a.after = model_weights(a.full, prm, -std::numeric_limits<double>::infinity());
  return a;
}
/// One table's weights at a shared angle; `a0` = burn_start(burn, dur).
Weights table_weights(const SharedAngle& a, const EnergiesParams& prm, double burn, double a0,
                      double dur) noexcept {
  const double phi = a.full.phi;
  if (dur > 0.0) {
    const double s = phi > kTwoPi ? phi - kFourPi : phi;
    if (s > a0 && s < a0 + dur) {
      const double xb = burned_fraction(s - a0, dur, prm);
      Weights w;
      w.map = (1.0 - xb) * prm.ivc_pressure_factor * a.full.ivc_poly;
      w.p3 = xb * a.full.c_poly;
      return w;
    }
  }
  return phi < burn ? a.before : a.after;
}
}  // namespace

LoadRls::LoadRls(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params)
    : engine_(engine), params_(params), kappa_(params.polytropic_kappa) {
  const CrankKinematics kin(engine);
  v_c_ = kin.clearance_volume_m3();
  v_ivc_ = kin.volume((540.0 + params.ivc_abdc_deg) * kDeg);
  rip_motored_ = std::pow(v_ivc_ / v_c_, ripple_kappas(params).comp);
  std::vector<double> e1, w1;
  nominal_wheel_edges(wheel, e1, w1);
  const int t = wheel.teeth();
  samples_ = 2 * t;
  std::vector<double> center(static_cast<std::size_t>(samples_));
  for (int k = 0; k < samples_; ++k) {
    const int rev = k / t;  // whole revolutions before sample k
    const double e = rev * kTwoPi + e1[static_cast<std::size_t>(k % t)];
    center[static_cast<std::size_t>(k)] =
        wrap4pi(e - 0.5 * w1[static_cast<std::size_t>(k % t)] - engine.tdc_offset_rad);
  }
  const std::uint64_t key = tables_key(center);
  std::vector<double> flat;
  const bool cached = cached_table("load-rls", key, flat, 0, [&](std::vector<double>& tab) {
    build_tables(kin, center);
    pack_tables(tab);
  });
  if (cached && !unpack_tables(flat)) build_tables(kin, center);  // cannot happen with a checked cache
  open_.assign(windows_tab_.size(), 0);
  ke_first_.assign(windows_tab_.size(), 0.0);
  w2_first_.assign(windows_tab_.size(), 0.0);
  reset();
}

// Every input of build_tables(): the engine (kinematics, firing positions), the tooth-period centres, the
// pressure model's parameters and the windows (the code itself is the cache's part of the key).
std::uint64_t LoadRls::tables_key(const std::vector<double>& center) const noexcept {
  const EngineGeometry& e = engine_;
  const EnergiesParams& p = params_;
  TableKey key;
  key.add(std::string_view("load-rls 2")).add(kMaxCylinders).add(kCentroids).add(samples_).add(center);
  key.add(e);
  key.add(p.window_start_btdc_deg).add(p.window_end_btdc_deg).add(p.polytropic_kappa).add(p.ivc_abdc_deg);
  key.add(p.evo_atdc_deg).add(p.blowdown_end_atdc_deg).add(p.exhaust_pressure_pa).add(p.ivc_pressure_factor);
  key.add(p.rls_window_shifts).add(p.burn_centroid_atdc_deg).add(p.burn_duration_deg);
  key.add(p.incycle_compression_kappa).add(p.incycle_expansion_kappa).add(p.burn_wiebe_a).add(p.burn_wiebe_m);
  return key.value();
}

// The closure coefficients, the windows' gas-work integrals and the ripple tables (precomputed, see the
// header's rule 3).
void LoadRls::build_tables(const CrankKinematics& kin, const std::vector<double>& center) {
  const EnergiesParams& params = params_;
  const int n = engine_.cylinders;
  windows_tab_.clear();
  window_first_of_.assign(static_cast<std::size_t>(samples_), -1);
  window_last_of_.assign(static_cast<std::size_t>(samples_), -1);
  const double step = 0.05 * kDeg;
  // Full-cycle ∮p dV coefficients of one cylinder (local angle), one set per burn centroid 0..kCentroids−1
  // deg. The burn-independent terms are tabulated once over the integration grid (same φ sequence for every
  // centroid).
  std::vector<AngleTerms> grid;
  grid.reserve(static_cast<std::size_t>(kFourPi / step) + 2);
  for (double phi = 0.5 * step; phi < kFourPi;) {  // the same φ sequence as before (repeated addition)
    grid.push_back(angle_terms(phi, kin, params, v_ivc_, v_c_, closure_kappas(params)));
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
  const double zero = 0.0;
  std::size_t ib = 0;
  for (int ci = 0; ci < kCentroids; ++ci) {
    const double burn = ci * kDeg;
    while (ib < grid.size() && grid[ib].phi < burn) ++ib;  // burn grows with ci
    const bool last = ci == kCentroids - 1;
    double cm = 0.0, ce = 0.0, cp = 0.0;
    for (std::size_t i = 0; i < ib; ++i) {
      const double none = zero * (grid[i].dvol * step);
      cm += prod[i][0];
      cp += none;
      if (last) ce += none;
    }
    for (std::size_t i = ib; i < grid.size(); ++i) {
      cm += prod[i][1];
      cp += prod[i][3];
    }
    if (last)
      for (std::size_t i = ib; i < grid.size(); ++i) ce += prod[i][2];
    cyc_map_[static_cast<std::size_t>(ci)] = cm;
    cyc_exh_ = ce;
    cyc_p3_[static_cast<std::size_t>(ci)] = cp;
  }
  const double pitch = kFourPi / samples_;
  for (int m = 0; m < n; ++m)
    for (int shift = 0; shift < std::max(1, params.rls_window_shifts); ++shift) {
      const double tdc = kFourPi * m / n - shift * pitch;
      const double a = tdc - params.window_start_btdc_deg * kDeg;
      const double b = tdc - params.window_end_btdc_deg * kDeg;
      // Teeth whose period centre lies in [a, b] (relative distance from a, wrapped).
      int first = -1, last = -1;
      double best_first = 1e9, best_last = -1e9;
      for (int k = 0; k < samples_; ++k) {
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
      if (first < 0 || last < 0 || first == last) continue;  // window narrower than a tooth: unusable
      Window win;
      win.first = first;
      win.last = last;
      win.c_first = center[static_cast<std::size_t>(first)];
      win.c_last = center[static_cast<std::size_t>(last)];
      win.span = wrap4pi(win.c_last - win.c_first);
      win.j_first = kin.inertia(win.c_first);
      win.j_last = kin.inertia(win.c_last);
      const int steps = static_cast<int>(std::ceil(win.span / step));
      const double h = win.span / steps;
      for (int q = 0; q < n; ++q) {
        const double phase = kFourPi * q / n;
        for (int i = 0; i < steps; ++i) {
          const double th = win.c_first + (i + 0.5) * h;
          const double phi = wrap4pi(th - phase);
          const double burn = params.burn_centroid_atdc_deg * kDeg;
          const AngleTerms at =
              angle_terms_for(phi, kin, params, v_ivc_, v_c_, burn, 0.0, closure_kappas(params));
          const Weights w = model_weights(at, params, burn);
          const double dv = at.dvol * h;  // dV_j/dθ dθ = A R f(θ − φ_j) dθ (EN-9)
          win.k_map += w.map * dv;
          win.k_exh += w.exh * dv;
          win.k_p3[static_cast<std::size_t>(q)] += w.p3 * dv;
          win.k_cc -= dv;
        }
      }
      if (window_first_of_[static_cast<std::size_t>(first)] >= 0 ||
          window_last_of_[static_cast<std::size_t>(last)] >= 0) {
        continue;  // irregular wheel: two shifts mapped onto the same teeth
      }
      window_first_of_[static_cast<std::size_t>(first)] = static_cast<int>(windows_tab_.size());
      window_last_of_[static_cast<std::size_t>(last)] = static_cast<int>(windows_tab_.size());
      win.position = m;
      windows_tab_.push_back(win);
    }
  // The group's closing window: the smallest shift kept (it ends at window_end_btdc, the latest).
  for (int m = 0; m < n; ++m) {
    for (std::size_t w = 0; w < windows_tab_.size(); ++w) {
      if (windows_tab_[w].position == m) {
        windows_tab_[w].closes_group = true;
        break;  // pushed in shift order: the first one of a position has the smallest shift
      }
    }
  }
  build_ripple(center);
}

// The tables as one array of doubles for the table cache (integers are exact in a double): the closure
// coefficients, the ripple tables, then each window.
namespace {
constexpr std::size_t kWindowFields = 13 + kMaxCylinders;
}  // namespace

void LoadRls::pack_tables(std::vector<double>& t) const {
  t.clear();
  t.push_back(static_cast<double>(windows_tab_.size()));
  t.insert(t.end(), cyc_map_.begin(), cyc_map_.end());
  t.insert(t.end(), cyc_p3_.begin(), cyc_p3_.end());
  t.push_back(cyc_exh_);
  t.insert(t.end(), rip_cm_.begin(), rip_cm_.end());
  t.insert(t.end(), rip_cp_.begin(), rip_cp_.end());
  t.insert(t.end(), rip_ce_.begin(), rip_ce_.end());
  t.insert(t.end(), rip_map_.begin(), rip_map_.end());
  t.insert(t.end(), rip_const_.begin(), rip_const_.end());
  t.insert(t.end(), rip_p3_.begin(), rip_p3_.end());
  for (int k = 0; k < samples_; ++k) {
    t.push_back(window_first_of_[static_cast<std::size_t>(k)]);
    t.push_back(window_last_of_[static_cast<std::size_t>(k)]);
  }
  for (const Window& w : windows_tab_) {
    t.insert(t.end(), {static_cast<double>(w.first), static_cast<double>(w.last), w.c_first, w.c_last, w.span,
                       w.j_first, w.j_last, w.k_map, w.k_exh, w.k_cc, static_cast<double>(w.position),
                       w.closes_group ? 1.0 : 0.0});
    t.insert(t.end(), w.k_p3.begin(), w.k_p3.end());
    t.push_back(0.0);  // spare: keeps kWindowFields a round count
  }
}

bool LoadRls::unpack_tables(const std::vector<double>& t) {
  const auto ks = static_cast<std::size_t>(samples_);
  constexpr auto kt = static_cast<std::size_t>(kRippleTables);
  const std::size_t head = 1 + 2 * kCentroids + 1 + 3 * kt + kt * ks * (2 + kMaxCylinders) + 2 * ks;
  if (t.size() < head) return false;
  const double nw = t[0];
  if (!(nw >= 0.0) || t.size() != head + static_cast<std::size_t>(nw) * kWindowFields) return false;
  auto it = t.begin() + 1;
  auto take = [&it](auto& dst) {
    std::copy(it, it + static_cast<std::ptrdiff_t>(dst.size()), dst.begin());
    it += static_cast<std::ptrdiff_t>(dst.size());
  };
  take(cyc_map_);
  take(cyc_p3_);
  cyc_exh_ = *it++;
  take(rip_cm_);
  take(rip_cp_);
  take(rip_ce_);
  rip_map_.resize(kt * ks);
  rip_const_.resize(kt * ks);
  rip_p3_.resize(kt * ks * kMaxCylinders);
  take(rip_map_);
  take(rip_const_);
  take(rip_p3_);
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
    std::copy(it + 12, it + 12 + kMaxCylinders, w.k_p3.begin());
    it += static_cast<std::ptrdiff_t>(kWindowFields);
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
  RippleBuild b;
  b.dur = params_.burn_duration_deg * kDeg;
  for (std::size_t t = 0; t < b.burn.size(); ++t) {
    b.burn[t] =
        (params_.burn_centroid_atdc_deg + (static_cast<int>(t) - kRippleBase) * kRippleStepDeg) * kDeg;
    b.start[t] = burn_start(b.burn[t], b.dur, params_);
  }
  build_ripple_closure(b);
  build_ripple_samples(center, b);
}

// Full-cycle closure of the ripple model for one cylinder (ripple_p3), every table: ∮p dV per Pa of MAP and
// of p3, and the p_exh part (J). Each angle's burn-independent terms are computed once for all tables.
void LoadRls::build_ripple_closure(const RippleBuild& b) {
  const CrankKinematics kin(engine_);
  const Kappas kap = ripple_kappas(params_);
  std::array<double, kRippleTables> cm{}, cp{}, ce{};
  constexpr int kClosureSteps = 720 * 4;  // 0.25° steps over the cycle
  for (int i = 0; i < kClosureSteps; ++i) {
    const double phi = (i + 0.5) * kFourPi / kClosureSteps;
    const SharedAngle sa = shared_angle(phi, kin, params_, v_ivc_, v_c_, kap);
    const double dv = sa.dvol * kFourPi / kClosureSteps;
    for (std::size_t t = 0; t < cm.size(); ++t) {
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

// Per-sample gas-torque ripple of every table: the pressure model's work over [c_k, c_{k+1}] per unit of each
// input, divided by the step, minus the 720° mean (the mean indicated torque is the cycle balance's, not
// this).
void LoadRls::build_ripple_samples(const std::vector<double>& center, const RippleBuild& b) {
  const CrankKinematics kin(engine_);
  const Kappas kap = ripple_kappas(params_);
  const int n = engine_.cylinders;
  const auto ks = static_cast<std::size_t>(samples_);
  constexpr std::size_t kt = kRippleTables;
  std::array<double, kt> wm{}, wc{};
  std::array<std::array<double, kMaxCylinders>, kt> wp{};
  for (int k = 0; k < samples_; ++k) {
    const double c0 = center[static_cast<std::size_t>(k)];
    const double span = wrap4pi(center[static_cast<std::size_t>((k + 1) % samples_)] - c0);
    const int steps = std::max(4, static_cast<int>(std::ceil(span / (0.25 * kDeg))));
    const double h = span / steps;
    std::array<double, kt> tm{}, tc{};
    std::array<std::array<double, kMaxCylinders>, kt> tp{};
    for (int q = 0; q < n; ++q) {
      for (int i = 0; i < steps; ++i) {
        const double phi = wrap4pi(c0 + (i + 0.5) * h - kFourPi * q / n);
        const SharedAngle sa = shared_angle(phi, kin, params_, v_ivc_, v_c_, kap);
        const double dv = sa.dvol * h;
        for (std::size_t t = 0; t < kt; ++t) {
          const Weights w = table_weights(sa, params_, b.burn[t], b.start[t], b.dur);
          tm[t] += w.map * dv;
          tc[t] += (w.exh * params_.exhaust_pressure_pa - engine_.crankcase_pressure_pa) * dv;
          tp[t][static_cast<std::size_t>(q)] += w.p3 * dv;
        }
      }
    }
    const auto kk = static_cast<std::size_t>(k);
    for (std::size_t t = 0; t < kt; ++t) {
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
  for (std::size_t t = 0; t < kt; ++t) {
    for (std::size_t k = 0; k < ks; ++k) {
      rip_map_[t * ks + k] -= wm[t] / kFourPi;
      rip_const_[t * ks + k] -= wc[t] / kFourPi;
      for (int q = 0; q < n; ++q)
        rip_p3_[(t * ks + k) * kMaxCylinders + static_cast<std::size_t>(q)] -=
            wp[t][static_cast<std::size_t>(q)] / kFourPi;
    }
  }
}

void LoadRls::ripple_table(double centroid_deg, int& t, double& frac) const noexcept {
  const double x = std::isfinite(centroid_deg)
                       ? kRippleBase + (centroid_deg - params_.burn_centroid_atdc_deg) / kRippleStepDeg
                       : static_cast<double>(kRippleBase);
  const double c = std::clamp(x, 0.0, static_cast<double>(kRippleTables - 1));
  t = std::min(static_cast<int>(c), kRippleTables - 2);
  frac = c - t;
}

void LoadRls::ripple_p3(double map_pa, const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid,
                        std::array<double, kMaxCylinders>& p3_pa, int t) const noexcept {
  const auto tt = static_cast<std::size_t>(std::clamp(t, 0, kRippleTables - 1));
  for (int q = 0; q < engine_.cylinders; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    p3_pa[qi] = works_valid ? (cyl_work_j[qi] - rip_cm_[tt] * map_pa - rip_ce_[tt]) / rip_cp_[tt]
                            : params_.ivc_pressure_factor * map_pa * rip_motored_;
  }
}

double LoadRls::gas_ripple_nm(int k, double map_pa, const std::array<double, kMaxCylinders>& p3_pa,
                              int t) const noexcept {
  if (k < 0 || k >= samples_ || t < 0 || t >= kRippleTables) return 0.0;
  const auto kk =
      static_cast<std::size_t>(t) * static_cast<std::size_t>(samples_) + static_cast<std::size_t>(k);
  double v = rip_map_[kk] * map_pa + rip_const_[kk];
  for (int q = 0; q < engine_.cylinders; ++q)
    v += rip_p3_[kk * kMaxCylinders + static_cast<std::size_t>(q)] * p3_pa[static_cast<std::size_t>(q)];
  return v;
}

void LoadRls::reset() noexcept {
  std::fill(open_.begin(), open_.end(), 0);
  expected_tooth_ = -1;
  theta_ = {engine_.j_rot_kgm2, 0.0};
  p_ = {1e-4, 0.0, 0.0, 1e6};
  resid_var_ = 0.0;
  windows_ = 0;
  est_ = TorqueEstimate{};
  grp_sum_.fill(0.0);
  grp_n_.fill(0);
  hist_head_ = hist_count_ = 0;
  z_cycle_ = 0.0;
  z_valid_ = false;
  d_var_ = 0.0;
  zd_var_ = 0.0;
  d_n_ = 0;
  blend_ = 0.0;
  hold_groups_ = 0;
  load_changes_ = 0;
  fast_windows_ = 0;
  cusum_pos_ = cusum_neg_ = 0.0;
  trk_theta_ = 0.0;
  trk_p_ = 1e6;
  trk_ = TorqueEstimate{};
}

namespace {
constexpr int kFastCycles = 4;  // tracker memory held at one cycle for this many cycles after a load change
constexpr double kZConfirm = 2.5;  // |z − tracker| must exceed this many σ of its steady spread
constexpr int kStatsCycles = 10;   // steady cycles of innovation statistics before changes are detected
}  // namespace

void LoadRls::track(double obs, const Window& win) noexcept {
  const auto m = static_cast<std::size_t>(win.position);
  grp_sum_[m] += obs;
  ++grp_n_[m];
  if (!win.closes_group) return;
  const int n = engine_.cylinders;
  const double h = grp_sum_[m] / grp_n_[m];
  grp_sum_[m] = 0.0;
  grp_n_[m] = 0;
  constexpr int kHist = kMaxCylinders + 1;
  hist_head_ = (hist_head_ + 1) % kHist;
  hist_[static_cast<std::size_t>(hist_head_)] = h;
  hist_count_ = std::min(hist_count_ + 1, n + 1);
  if (hist_count_ < n + 1) return;
  // Trapezoid over the n firing intervals spanned by the last n + 1 firings (the same 720° as the energy
  // balance).
  double z = 0.0;
  for (int j = 0; j <= n; ++j) {
    const double v = hist_[static_cast<std::size_t>((hist_head_ - j + kHist) % kHist)];
    z += (j == 0 || j == n) ? 0.5 * v : v;
  }
  z_cycle_ = z / n;
  z_valid_ = true;
  if (params_.rls_change_threshold <= 0.0) return;  // rule 4 off: the RLS alone
  // Two-sided CUSUM (Page) on the per-firing innovations e = h − RLS in units of their steady 1σ: persistent
  // shifts add up, zero-mean noise drains by the allowance of 0.5σ per firing.
  const double e = h - trk_theta_;
  const double floor_sd = params_.rls_step_min_sd_nm;
  const double sd = std::sqrt(std::max(d_var_, floor_sd * floor_sd));
  const bool ready =
      windows_ >= static_cast<std::uint64_t>(params_.rls_min_windows) && d_n_ >= kStatsCycles * n;
  constexpr double kAllowance = 0.5;
  cusum_pos_ = std::max(0.0, cusum_pos_ + e / sd - kAllowance);
  cusum_neg_ = std::max(0.0, cusum_neg_ - e / sd - kAllowance);
  // The cycle mean must also have left the tracker by 3σ of its own steady spread: z − RLS is correlated from
  // firing to firing (z spans n + 1 firings, and at 4000 rpm the jitter noise wanders over several cycles),
  // which alone would let the CUSUM fire on noise.
  const double zd = z_cycle_ - trk_theta_;
  const double zsd = std::sqrt(std::max(zd_var_, floor_sd * floor_sd));
  // Only where the cycle mean is informative: at high speed its jitter noise (±10-20 N m at 4000 rpm) is
  // larger than the changes worth tracking, and the RLS average is the better value even in transients.
  const bool informative = zsd <= params_.rls_change_max_sd_nm;
  if (ready && informative && std::fabs(zd) > kZConfirm * zsd &&
      (cusum_pos_ > params_.rls_change_threshold || cusum_neg_ > params_.rls_change_threshold)) {
    // A load change: restart the tracker's memory at the cycle mean (worth one cycle of windows) and report
    // the cycle mean for one cycle.
    trk_theta_ = z_cycle_;
    trk_p_ = 1.0 / std::max(1.0, static_cast<double>(windows_tab_.size()));
    fast_windows_ = kFastCycles * static_cast<int>(windows_tab_.size());
    blend_ = 1.0;
    hold_groups_ = n;
    cusum_pos_ = cusum_neg_ = 0.0;
    ++load_changes_;
    return;
  }
  if (hold_groups_ > 0) {
    --hold_groups_;
    blend_ = 1.0;
    cusum_pos_ = cusum_neg_ = 0.0;
    return;
  }
  blend_ = 0.0;
  if (std::fabs(e) > 3.0 * sd && d_n_ >= kStatsCycles * n)
    return;  // an outlier or a change: not a steady sample
  ++d_n_;
  const double a = std::max(1.0 / d_n_, 0.05);
  d_var_ += a * (e * e - d_var_);
  zd_var_ += a * (zd * zd - zd_var_);
}

double LoadRls::centroid_deg(double spark_advance_deg) const noexcept {
  const double c = std::isfinite(spark_advance_deg) ? params_.burn_delay_deg - spark_advance_deg
                                                    : params_.burn_centroid_atdc_deg;
  return std::clamp(c, 0.0, static_cast<double>(kCentroids - 1));
}

double LoadRls::expansion_p3(double work_j, double map_pa, double spark_advance_deg) const noexcept {
  // Linear interpolation of the closure coefficients in the burn centroid.
  const double c = centroid_deg(spark_advance_deg);
  const int i = std::min(static_cast<int>(c), kCentroids - 2);
  const double f = c - i;
  const auto ii = static_cast<std::size_t>(i);
  const double cm = cyc_map_[ii] + f * (cyc_map_[ii + 1] - cyc_map_[ii]);
  const double cp = cyc_p3_[ii] + f * (cyc_p3_[ii + 1] - cyc_p3_[ii]);
  return (work_j - cm * map_pa - cyc_exh_ * params_.exhaust_pressure_pa) / cp;
}

double LoadRls::model_pressure(double local_rad, double map_pa, double p3_pa,
                               double spark_advance_deg) const noexcept {
  const CrankKinematics kin(engine_);
  const Weights w =
      model_weights(angle_terms(wrap4pi(local_rad), kin, params_, v_ivc_, v_c_, closure_kappas(params_)),
                    params_, centroid_deg(spark_advance_deg) * kDeg);
  return w.map * map_pa + w.exh * params_.exhaust_pressure_pa + w.p3 * p3_pa;
}

double LoadRls::motored_p3(double map_pa) const noexcept {
  // Motored: the compression end state p_IVC (V_IVC/V_c)^κ expands back along the same polytrope.
  return params_.ivc_pressure_factor * map_pa * std::pow(v_ivc_ / v_c_, kappa_);
}

double LoadRls::motored_torque_nm(double map_pa) const noexcept {
  // Motored: no heat release, the centroid does not matter (use 0).
  const double w =
      cyc_map_[0] * map_pa + cyc_exh_ * params_.exhaust_pressure_pa + cyc_p3_[0] * motored_p3(map_pa);
  return engine_.cylinders * w / kFourPi;
}

double LoadRls::window_gas_work(int w, double map_pa,
                                const std::array<double, kMaxCylinders>& p3_pa) const noexcept {
  const Window& win = windows_tab_[static_cast<std::size_t>(w)];
  double work =
      win.k_map * map_pa + win.k_exh * params_.exhaust_pressure_pa + win.k_cc * engine_.crankcase_pressure_pa;
  for (int q = 0; q < engine_.cylinders; ++q)
    work += win.k_p3[static_cast<std::size_t>(q)] * p3_pa[static_cast<std::size_t>(q)];
  return work;
}

// One RLS step on the window's observation y (N m) with angle-mean θ̈ phi_a (rad/s²); returns the a-priori
// error.
double LoadRls::rls_step(double y, double phi_a) noexcept {
  const double lam = params_.rls_forgetting;
  double err;
  if (params_.rls_estimate_inertia) {
    // EN-15: Q = P ψ (λ + ψᵀPψ)⁻¹, Θ += Q (y − ψᵀΘ), P = (P − Q ψᵀ P)/λ, ψ = [θ̈, 1].
    const double psi0 = phi_a, psi1 = 1.0;
    const double pp0 = p_[0] * psi0 + p_[1] * psi1, pp1 = p_[2] * psi0 + p_[3] * psi1;
    const double den = lam + psi0 * pp0 + psi1 * pp1;
    err = y - (psi0 * theta_[0] + psi1 * theta_[1]);
    last_obs_ = y - theta_[0] * psi0;
    const double q0 = pp0 / den, q1 = pp1 / den;
    theta_[0] += q0 * err;
    theta_[1] += q1 * err;
    const double n00 = (p_[0] - q0 * pp0) / lam, n01 = (p_[1] - q0 * pp1) / lam;
    const double n11 = (p_[3] - q1 * pp1) / lam;
    p_ = {n00, n01, n01, n11};
  } else {
    // Known J_rot: scalar RLS with forgetting on y − J_rot θ̈ = T_load*.
    const double yy = y - engine_.j_rot_kgm2 * phi_a;
    last_obs_ = yy;
    err = yy - theta_[1];
    const double den = lam + p_[3];
    const double q = p_[3] / den;
    theta_[1] += q * err;
    p_[3] = (p_[3] - q * p_[3]) / lam;
  }
  return err;
}

// After a window: residual variance, the tracker RLS (rule 4), the estimates and their uncertainties.
void LoadRls::publish(std::int64_t t_ns, double err, const Window& win) noexcept {
  const double lam = params_.rls_forgetting;
  ++windows_;
  const double a = windows_ < 20 ? 1.0 / static_cast<double>(windows_) : 0.05;
  resid_var_ += a * (err * err - resid_var_);
  // Tracker RLS (rule 4): the same scalar recursion on the same observation, re-seeded at load changes.
  {
    const double yt = last_obs_;
    const double q = trk_p_ / (lam + trk_p_);
    trk_theta_ += q * (yt - trk_theta_);
    trk_p_ = (trk_p_ - q * trk_p_) / lam;
    if (fast_windows_ > 0) {
      // After a load change the load keeps moving (dyno controller settling): hold the memory at one cycle of
      // windows for a few cycles, then let it grow back to the RLS memory.
      --fast_windows_;
      trk_p_ = std::max(trk_p_, 1.0 / std::max(1.0, static_cast<double>(windows_tab_.size())));
    }
  }
  track(last_obs_, win);
  est_.t_ns = t_ns;
  est_.torque_nm = theta_[1];
  // Effective sample count of the forgetting factor: (1 + λ)/(1 − λ).
  const double n_eff = std::min<double>(static_cast<double>(windows_), (1.0 + lam) / (1.0 - lam));
  const double sd_rls = std::sqrt(resid_var_ / n_eff);
  est_.uncertainty = sd_rls;
  est_.health = windows_ >= static_cast<std::uint64_t>(params_.rls_min_windows) ? Health::kValid
                                                                                : Health::kNotConverged;
  trk_ = est_;
  if (z_valid_ && blend_ > 0.0) {
    const double floor_sd = params_.rls_step_min_sd_nm;
    trk_.torque_nm = z_cycle_;
    trk_.uncertainty = std::sqrt(std::max(d_var_, floor_sd * floor_sd));
  } else {
    trk_.torque_nm = trk_theta_;
  }
}

bool LoadRls::update(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
                     const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept {
  if (!s.synced || s.tooth < 0 || s.tooth >= samples_ || !(s.dt_s > 0.0) || !(s.width_rad > 0.0) ||
      (expected_tooth_ >= 0 && s.tooth != expected_tooth_)) {
    std::fill(open_.begin(), open_.end(), 0);
    expected_tooth_ = s.synced && s.tooth >= 0 && s.tooth < samples_ ? (s.tooth + 1) % samples_ : -1;
    grp_sum_.fill(0.0);  // no cycle mean across a hole
    grp_n_.fill(0);
    hist_count_ = 0;
    z_valid_ = false;
    blend_ = 0.0;
    return false;
  }
  expected_tooth_ = (s.tooth + 1) % samples_;
  const auto k = static_cast<std::size_t>(s.tooth);
  const double w2 = (s.width_rad / s.dt_s) * (s.width_rad / s.dt_s);
  const int opened = window_first_of_[k];
  if (opened >= 0) {
    const auto oi = static_cast<std::size_t>(opened);
    open_[oi] = 1;
    ke_first_[oi] = 0.5 * (windows_tab_[oi].j_first - engine_.j_rot_kgm2) * w2;
    w2_first_[oi] = w2;
  }
  const int closed = window_last_of_[k];
  if (closed < 0 || !open_[static_cast<std::size_t>(closed)]) return false;
  const auto ci = static_cast<std::size_t>(closed);
  open_[ci] = 0;
  if (!map_valid || !std::isfinite(map_pa)) {
    est_.health = Health::kStaleInput;
    return false;
  }
  const Window& win = windows_tab_[static_cast<std::size_t>(closed)];
  std::array<double, kMaxCylinders> p3{};
  for (int q = 0; q < engine_.cylinders; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    p3[qi] = params_.model_expansion_cylinder && works_valid
                 ? expansion_p3(cyl_work_j[qi], map_pa, spark_advance_deg)
                 : motored_p3(map_pa);
    if (!params_.model_expansion_cylinder)
      p3[qi] = 0.0;  // paper's simplification: no other cylinder's gas torque
  }
  // Paper's simplification keeps only the compressing cylinder: drop every cylinder's expansion/exhaust
  // terms.
  double gas = window_gas_work(closed, map_pa, p3);
  if (!params_.model_expansion_cylinder) gas -= win.k_exh * params_.exhaust_pressure_pa;
  const double ke_rel = 0.5 * (win.j_last - engine_.j_rot_kgm2) * w2 - ke_first_[ci];
  const double y = (gas - ke_rel) / win.span;                  // energy form of EN-11
  const double phi_a = 0.5 * (w2 - w2_first_[ci]) / win.span;  // angle-mean θ̈ (rad/s²)
  if (!std::isfinite(y) || !std::isfinite(phi_a)) {
    est_.health = Health::kInvalidInput;
    return false;
  }
  last_y_ = y;
  const double err = rls_step(y, phi_a);
  if (!std::isfinite(theta_[0]) || !std::isfinite(theta_[1])) {
    reset();
    est_.health = Health::kNumerical;
    return false;
  }
  publish(s.t_ns, err, win);
  return true;
}

}  // namespace torqued
