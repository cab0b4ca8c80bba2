#include "fuel_torque.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
Health worst_health(Health a, Health b) noexcept {
  return static_cast<std::uint8_t>(a) > static_cast<std::uint8_t>(b) ? a : b;
}
}  // namespace

FuelTorque::FuelTorque(const EngineGeometry& engine, const FuelTorqueParams& params) noexcept
    : params_(params),
      n_cyl_(engine.cylinders),
      vd_4pi_(std::numbers::pi * 0.25 * engine.bore_m * engine.bore_m * engine.stroke_m * engine.cylinders /
              kFourPi) {
  reset();
}

void FuelTorque::reset() noexcept {
  st_ = FuelTorqueState{};
  st_.theta = {params_.eta_prior, params_.p_exh_prior_pa * vd_4pi_};
  const double s1 = params_.eta_prior_sd, s2 = params_.p_exh_prior_sd_pa * vd_4pi_;
  st_.p = {s1 * s1, 0.0, 0.0, s2 * s2};
  st_.resid_var = params_.residual_sd_nm * params_.residual_sd_nm;
}

TorqueEstimate FuelTorque::estimate(std::int64_t t_ns, double fuel_kg, double map_pa) const noexcept {
  TorqueEstimate e;
  e.t_ns = t_ns;
  if (!std::isfinite(fuel_kg) || !std::isfinite(map_pa)) {
    e.health = Health::kInvalidInput;
    return e;
  }
  const double f = n_cyl_ * fuel_kg * params_.fuel_lhv_j_kg / kFourPi;
  e.torque_nm = st_.theta[0] * f + map_pa * vd_4pi_ - st_.theta[1];
  // 1σ: measured residual scale (68th percentile once valid, RMS before) plus the parameter uncertainty here.
  const double v_par = f * f * st_.p[0] - 2.0 * f * st_.p[1] + st_.p[3];
  const double r = st_.cover.sd > 0.0 ? st_.cover.sd * st_.cover.sd : st_.resid_var;
  e.uncertainty = std::sqrt(r + std::max(0.0, v_par));
  e.health = valid() ? Health::kValid : Health::kNotConverged;
  return e;
}

TorqueEstimate FuelTorque::estimate_window(std::int64_t t_ns, const FuelWindow& w,
                                           const TorqueEstimate& motored) const noexcept {
  const int n = w.fired + w.cut;
  if (!w.valid || n <= 0) {
    TorqueEstimate e;
    e.t_ns = t_ns;
    e.health = Health::kStaleInput;
    return e;
  }
  const double frac = static_cast<double>(w.fired) / n;
  const TorqueEstimate fired = estimate(t_ns, w.fired > 0 ? w.fuel_kg : 0.0, w.map_fired_pa);
  const TorqueEstimate cut = motored.health == Health::kValid ? motored : estimate(t_ns, 0.0, w.map_cut_pa);
  TorqueEstimate e = w.fired > 0 ? fired : cut;
  e.torque_nm = frac * fired.torque_nm + (1.0 - frac) * cut.torque_nm;
  const double sd = frac * fired.uncertainty + (1.0 - frac) * cut.uncertainty;
  // Spread of one event's share (1/n of the window) of the model torque across the window: fuel and MAP
  // changing, or a cut-off edge inside. Near the window's edges an event's work is partly its neighbour's.
  const double per_kg = n_cyl_ * params_.fuel_lhv_j_kg / kFourPi * st_.theta[0];
  double spread = per_kg * (w.fuel_max_kg - w.fuel_min_kg) + vd_4pi_ * (w.map_max_pa - w.map_min_pa);
  if (w.fired > 0 && w.cut > 0) spread += std::fabs(fired.torque_nm - cut.torque_nm);
  e.uncertainty = std::hypot(sd, params_.transient_sd_scale * spread / n);
  if (w.fired > 0 && w.cut > 0) e.health = worst_health(fired.health, cut.health);
  return e;
}

bool FuelTorque::learn(double fuel_kg, double map_pa, double t_ind_ref) noexcept {
  if (!std::isfinite(fuel_kg) || !std::isfinite(map_pa) || !std::isfinite(t_ind_ref) || !(fuel_kg > 0.0))
    return false;
  const double phi[2] = {n_cyl_ * fuel_kg * params_.fuel_lhv_j_kg / kFourPi, -1.0};
  const double y = t_ind_ref - map_pa * vd_4pi_;
  const double err = y - (phi[0] * st_.theta[0] + phi[1] * st_.theta[1]);
  // 5σ outlier gate. Its σ never falls below one reference's own noise (residual_sd_nm): a variance measured
  // on a few plateaus must not reject every new operating point, which would then never enter the model or
  // its claimed 1σ (the claimed σ shrank to 0.3 N m on an engine whose other points were 2-4 N m off).
  const double r = params_.residual_sd_nm * params_.residual_sd_nm;
  if (valid() && err * err > 25.0 * std::max(st_.resid_var, r)) return false;
  const double pphi[2] = {st_.p[0] * phi[0] + st_.p[1] * phi[1], st_.p[2] * phi[0] + st_.p[3] * phi[1]};
  const double lam = params_.forgetting;
  const double denom = lam * r + phi[0] * pphi[0] + phi[1] * pphi[1];
  if (!(denom > 0.0)) return false;
  const double k[2] = {pphi[0] / denom, pphi[1] / denom};
  st_.theta[0] += k[0] * err;
  st_.theta[1] += k[1] * err;
  std::array<double, 4> pn{};
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) {
      pn[static_cast<std::size_t>(2 * i + j)] =
          (st_.p[static_cast<std::size_t>(2 * i + j)] - k[i] * pphi[j]) / lam;
    }
  }
  pn[1] = pn[2] = 0.5 * (pn[1] + pn[2]);
  st_.p = pn;
  // Residual variance from the a-priori errors (includes the reference's own noise: conservative), the
  // gate's scale. Once valid, a running mean over every reference since (weight 1/k, floored at sd_ema), and
  // the claimed scale (CoverageScale, same weights): both cover the whole range of operating points learned,
  // not only the last plateau.
  const bool was_valid = valid();
  ++st_.references;
  const double kn = static_cast<double>(st_.references) - params_.min_references;
  const double w = was_valid && kn >= 1.0 ? std::max(1.0 / kn, params_.sd_ema) : params_.sd_ema;
  st_.resid_var += w * (err * err - st_.resid_var);
  if (was_valid) observe_coverage(err);
  return true;
}

void FuelTorque::observe_coverage(double err) noexcept {
  st_.cover.observe_from(std::sqrt(st_.resid_var), err, params_.sd_ema, params_.sd_floor_nm);
}

bool FuelTorque::import_state(const FuelTorqueState& s) noexcept {
  for (double v : s.theta) {
    if (!std::isfinite(v)) return false;
  }
  for (double v : s.p) {
    if (!std::isfinite(v)) return false;
  }
  if (!std::isfinite(s.resid_var) || s.resid_var < 0.0) return false;
  if (!std::isfinite(s.cover.sd) || s.cover.sd < 0.0) return false;
  st_ = s;
  return true;
}

}  // namespace torqued
