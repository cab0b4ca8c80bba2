#pragma once
// The load RLS's cylinder-pressure model (load_rls.hpp, rule 2), shared by its run-time part (load_rls.cpp)
// and its start-up tables (load_rls_tables.cpp). Internal to those two files.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <vector>

#include "crank_kinematics.hpp"
#include "params.hpp"

namespace torqued::load_rls_model {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2.0 * kPi;
inline constexpr double kFourPi = 4.0 * kPi;
inline constexpr double kDeg = kPi / 180.0;
inline double wrap4pi(double a) noexcept {
  // fmod's remainder is exact: inside [0, 4π) it is a, and in [4π, 8π) a − 4π, which is exact too (Sterbenz's
  // lemma), so these two need no fmod (the same bits).
  if (a >= 0.0 && a < kFourPi) return a;
  if (a >= kFourPi && a < 2.0 * kFourPi) return a - kFourPi;
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
inline Kappas closure_kappas(const EnergiesParams& prm) noexcept {
  return {prm.polytropic_kappa, prm.polytropic_kappa};
}
/// The in-cycle gas torque model's exponents: energies.incycle_*_kappa, 0 = energies.polytropic_kappa.
inline Kappas ripple_kappas(const EnergiesParams& prm) noexcept {
  return {prm.incycle_compression_kappa > 0.0 ? prm.incycle_compression_kappa : prm.polytropic_kappa,
          prm.incycle_expansion_kappa > 0.0 ? prm.incycle_expansion_kappa : prm.polytropic_kappa};
}
inline AngleTerms angle_terms(double phi, const CrankKinematics& kin, const EnergiesParams& prm, double v_ivc,
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
inline double burn_start(double burn, double dur, const EnergiesParams& prm) noexcept {
  if (prm.burn_wiebe_a <= 0.0) return burn - 0.5 * dur;
  return burn - dur * std::pow(std::numbers::ln2 / prm.burn_wiebe_a, 1.0 / (prm.burn_wiebe_m + 1.0));
}
/// Burned fraction `x` into a burn of duration `dur`: raised cosine, or the Wiebe function scaled to reach 1
/// at its end.
inline double burned_fraction(double x, double dur, const EnergiesParams& prm) noexcept {
  if (prm.burn_wiebe_a <= 0.0) return 0.5 * (1.0 - std::cos(kPi * x / dur));
  const double a = prm.burn_wiebe_a;
  return (1.0 - std::exp(-a * std::pow(x / dur, prm.burn_wiebe_m + 1.0))) / (1.0 - std::exp(-a));
}
/// angle_terms() with only the volume powers that model_weights(·, burn) (dur = 0) or the in-cycle model's
/// weights (dur > 0, table_weights) read at φ (the others stay 0): the same values where used, at half the
/// pow() calls.
inline AngleTerms angle_terms_for(double phi, const CrankKinematics& kin, const EnergiesParams& prm,
                                  double v_ivc, double v_c, double burn, double dur, Kappas kap) noexcept {
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

/// The full-cycle closure of centroids 0..n−1 (n = ib.size()) from the grid's products (before: MAP; after:
/// MAP, p_exh, p3): centroid c's MAP sum starts at its prefix's `pre[c]` and its p3 sum at 0, and both add
/// the after-burn products from ib[c] on. Eight centroids are advanced together over the grid (the compiler
/// vectorises them), each adding its own terms in the same order as a loop per centroid: identical sums.
inline void closure_sums(const std::vector<std::array<double, 4>>& prod, const std::vector<std::size_t>& ib,
                         const std::vector<double>& pre, double* cm_out, double* cp_out) noexcept {
  constexpr std::size_t kGroup = 8;
  const std::size_t n = ib.size(), end = prod.size();
  for (std::size_t c0 = 0; c0 < n; c0 += kGroup) {
    const std::size_t g = std::min(kGroup, n - c0);
    std::array<double, kGroup> cm{}, cp{};
    for (std::size_t j = 0; j < g; ++j) cm[j] = pre[c0 + j];
    const std::size_t all = ib[c0 + g - 1];  // from here on every centroid of the group adds
    for (std::size_t i = ib[c0]; i < all; ++i)
      for (std::size_t j = 0; j < g; ++j)
        if (i >= ib[c0 + j]) {
          cm[j] += prod[i][1];
          cp[j] += prod[i][3];
        }
    if (g == kGroup) {
      for (std::size_t i = all; i < end; ++i) {
        const double a = prod[i][1], b = prod[i][3];
        for (std::size_t j = 0; j < kGroup; ++j) {
          cm[j] += a;
          cp[j] += b;
        }
      }
    } else {
      for (std::size_t i = all; i < end; ++i)
        for (std::size_t j = 0; j < g; ++j) {
          cm[j] += prod[i][1];
          cp[j] += prod[i][3];
        }
    }
    std::copy(cm.begin(), cm.begin() + static_cast<std::ptrdiff_t>(g), cm_out + c0);
    std::copy(cp.begin(), cp.begin() + static_cast<std::ptrdiff_t>(g), cp_out + c0);
  }
}

/// Pressure-model weights at local angle φ after a cylinder's firing TDC: p = w_map·MAP + w_exh·p_exh +
/// w_p3·p3.
struct Weights {
  double map = 0.0, exh = 0.0, p3 = 0.0;
};
inline Weights model_weights(const AngleTerms& t, const EnergiesParams& prm, double burn_rad) noexcept {
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
/// Which volume powers some table built reads at φ: both where one reads its compression before its centroid
/// or its burn; else only those model_weights() after the burn reads ((V_c/V)^κ before the blowdown end,
/// (V_IVC/V)^κ from IVC). The others stay 0.
struct Powers {
  bool ivc = true, c = true;
};
/// The angle's terms with the powers in `need` (the same values as angle_terms() where computed); between the
/// blowdown end and IVC dV/dφ is the plain one, as angle_terms_for() takes it.
inline SharedAngle shared_angle(double phi, const CrankKinematics& kin, const EnergiesParams& prm,
                                double v_ivc, double v_c, Kappas kap, Powers need) noexcept {
  SharedAngle a;
  const double evo = prm.evo_atdc_deg * kDeg;
  const double bde = prm.blowdown_end_atdc_deg * kDeg;
  const double ivc = (540.0 + prm.ivc_abdc_deg) * kDeg;
  const bool plain = phi >= bde && phi < ivc;
  AngleTerms& t = a.full;
  t.phi = phi;
  if (need.ivc || need.c) {
    double v = 0.0;
    kin.volume_and_dvolume(phi, v, t.dvol);
    if (need.ivc) t.ivc_poly = std::pow(v_ivc / v, kap.comp);
    if (need.c) t.c_poly = std::pow(v_c / v, kap.exp);
  }
  t.blend = (phi >= evo && phi < bde) ? 0.5 * (1.0 + std::cos(kPi * (phi - evo) / (bde - evo))) : 0.0;
  a.dvol = plain ? kin.dvolume(phi) : t.dvol;
  a.before = model_weights(t, prm, std::numeric_limits<double>::infinity());
  a.after = model_weights(t, prm, -std::numeric_limits<double>::infinity());
  return a;
}
/// One table's weights at a shared angle; `a0` = burn_start(burn, dur).
inline Weights table_weights(const SharedAngle& a, const EnergiesParams& prm, double burn, double a0,
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

}  // namespace torqued::load_rls_model
