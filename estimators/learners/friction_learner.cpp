#include "friction_learner.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
// Scaled coefficients keep the 3x3 RLS well conditioned: θ = [C1, C2·1e3, C3·1e6], regressor [1, n/1e3,
// (n/1e3)²].
constexpr double kS2 = 1e3;
constexpr double kS3 = 1e6;
bool finite4(const std::array<double, 4>& c) noexcept {
  for (double v : c) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}
}  // namespace

std::array<double, 4> generic_friction_prior(double displacement_m3, double sign) noexcept {
  // Barnes-Moss (Heywood 1988 §13.5): fmep = 0.97 + 0.15 k + 0.05 k² bar, k = N/1000; T = fmep V_d / 4π.
  constexpr double kBar = 1e5;
  const double to_nm = displacement_m3 / (4.0 * std::numbers::pi);
  const double s = sign != 0.0 ? sign : 1.0;
  return {0.97 * kBar * to_nm / s, 0.15 * kBar * to_nm / kS2 / s, 0.05 * kBar * to_nm / kS3 / s, 0.0};
}

FrictionLearner::FrictionLearner(const FrictionParams& params) noexcept : params_(params), base_(params.c) {
  reset();
}

void FrictionLearner::reset() noexcept {
  theta_ = {base_[0], base_[1] * kS2, base_[2] * kS3};
  c4_ = base_[3];
  const double v = params_.prior_sd_nm * params_.prior_sd_nm;
  p_ = {v, 0, 0, 0, v, 0, 0, 0, v};
  p4_ = 2.5e-5;  // C4 prior 1σ = 5e-3 /°C
  have_idle_ref_ = false;
  idle_corr_nm_ = 0.0;
  idle_rpm_ = 0.0;
  idle_prior_n_ = 0;
  n_motoring_ = n_idle_ = n_rejected_ = 0;
  partial_ = false;
  gated_run_ = 0;
  gated_sign_ = 0.0;
  cover_ = CoverageScale{};
  ref_sd_nm_ = 0.0;
  level_ = 1.0;
  level_ratio_ = 0.0;
  level_info_ = 0.0;
}

double FrictionLearner::prior_level_sd() const noexcept {
  const double s0 = params_.prior_rel_sd;
  if (!level_active() || !(level_info_ > 0.0) || !(s0 > 0.0)) return s0;
  return 1.0 / std::sqrt(1.0 / (s0 * s0) + level_info_);
}

void FrictionLearner::update_level(double speed_rpm, double oil_temp_c, double friction_nm,
                                   double obs_sd_nm) noexcept {
  const double nk = speed_rpm / kS2;
  const double law =
      params_.sign * std::exp(c4_ * oil_temp_c) * (theta_[0] + theta_[1] * nk + theta_[2] * nk * nk);
  const double s0 = params_.prior_rel_sd;
  if (!(law > 0.0) || !(s0 > 0.0)) return;
  // Running mean of the ratios; the observation's 1σ is shared by every idle cycle: counted once.
  level_ratio_ += (friction_nm / law - level_ratio_) / static_cast<double>(n_idle_);
  const double sd = (obs_sd_nm > 0.0 ? obs_sd_nm : params_.learned_sd_nm) / law;
  level_info_ = 1.0 / (sd * sd);
  const double i0 = 1.0 / (s0 * s0);
  const double f =
      params_.idle_max_correction_frac;  // the idle evidence moves idle friction at most this much
  level_ = std::clamp((i0 + level_info_ * level_ratio_) / (i0 + level_info_), 1.0 - f, 1.0 + f);
}

bool FrictionLearner::gate_rejects(double err, double law_var) noexcept {
  if (n_motoring_ < static_cast<std::uint64_t>(params_.min_observations) ||
      !(params_.motoring_gate_sigma > 0.0))
    return false;
  const double var = params_.learned_sd_nm * params_.learned_sd_nm + std::max(0.0, law_var);
  const double g = params_.motoring_gate_sigma;
  if (err * err <= g * g * var) {
    gated_run_ = 0;
    return false;
  }
  const double side = err > 0.0 ? 1.0 : -1.0;
  gated_run_ = side == gated_sign_ ? gated_run_ + 1 : 1;
  gated_sign_ = side;
  if (gated_run_ >= params_.motoring_gate_reaccept) return false;  // consistent: the friction really moved
  return true;
}

bool FrictionLearner::observe_motoring(double speed_rpm, double oil_temp_c, double friction_nm,
                                       double obs_var_nm2) noexcept {
  if (!params_.learn) return false;
  if (!std::isfinite(speed_rpm) || !std::isfinite(oil_temp_c) || !std::isfinite(friction_nm) ||
      speed_rpm < params_.min_rpm || speed_rpm > params_.max_rpm) {
    ++n_rejected_;
    return false;
  }
  // EN-34: RLS with forgetting on y = φᵀθ, φ = s e^{C4 t} [1, n', n'²].
  const double nk = speed_rpm / kS2;
  const double e = params_.sign * std::exp(c4_ * oil_temp_c);
  const double phi[3] = {e, e * nk, e * nk * nk};
  double pphi[3];
  for (int i = 0; i < 3; ++i)
    pphi[i] = p_[i * 3 + 0] * phi[0] + p_[i * 3 + 1] * phi[1] + p_[i * 3 + 2] * phi[2];
  const double lam = params_.forgetting;
  // Weighted RLS with forgetting: K = Pφ / (λ r + φᵀPφ), r = the observation's variance in the unit one.
  const double r = std::isfinite(obs_var_nm2) ? std::max(1.0, obs_var_nm2) : 1.0;
  const double denom = lam * r + phi[0] * pphi[0] + phi[1] * pphi[1] + phi[2] * pphi[2];
  if (!(denom > 0.0) || !std::isfinite(denom)) {
    ++n_rejected_;
    return false;
  }
  if (level_active() && level_ != 1.0) {  // the first motoring observation: the RLS continues from s · prior
    for (double& t : theta_) t *= level_;
    level_ = 1.0;
  }
  const double y_hat = phi[0] * theta_[0] + phi[1] * theta_[1] + phi[2] * theta_[2];
  const double err = friction_nm - y_hat;
  if (gate_rejects(err, phi[0] * pphi[0] + phi[1] * pphi[1] + phi[2] * pphi[2])) {
    ++n_rejected_;
    return false;
  }
  const double ref_sd = std::isfinite(obs_var_nm2) ? std::sqrt(std::max(0.0, obs_var_nm2)) : 0.0;
  ref_sd_nm_ = n_motoring_ == 0 ? ref_sd : std::min(ref_sd_nm_, ref_sd);
  if (n_motoring_ >= static_cast<std::uint64_t>(params_.min_observations)) {
    cover_.observe_from(params_.learned_sd_nm, err, params_.residual_gain_min, params_.residual_sd_floor_nm);
  }
  std::array<double, 9> pn{};
  for (int i = 0; i < 3; ++i) {
    const double k = pphi[i] / denom;
    theta_[static_cast<std::size_t>(i)] += k * err;
    for (int j = 0; j < 3; ++j) {
      pn[static_cast<std::size_t>(i * 3 + j)] = (p_[static_cast<std::size_t>(i * 3 + j)] - k * pphi[j]) / lam;
    }
  }
  // Keep P symmetric and bounded by the prior (forgetting without excitation would blow it up).
  const double pmax = params_.prior_sd_nm * params_.prior_sd_nm;
  for (int i = 0; i < 3; ++i) {
    for (int j = i + 1; j < 3; ++j) {
      const double m =
          0.5 * (pn[static_cast<std::size_t>(i * 3 + j)] + pn[static_cast<std::size_t>(j * 3 + i)]);
      pn[static_cast<std::size_t>(i * 3 + j)] = pn[static_cast<std::size_t>(j * 3 + i)] = m;
    }
    if (pn[static_cast<std::size_t>(i * 4)] > pmax) {
      const double s = pmax / pn[static_cast<std::size_t>(i * 4)];
      for (int j = 0; j < 3; ++j) {
        pn[static_cast<std::size_t>(i * 3 + j)] *= std::sqrt(s);
        pn[static_cast<std::size_t>(j * 3 + i)] *= std::sqrt(s);
      }
    }
  }
  p_ = pn;
  ++n_motoring_;
  return true;
}

bool FrictionLearner::observe_idle(double speed_rpm, double oil_temp_c, double friction_nm, bool scale_prior,
                                   double obs_sd_nm) noexcept {
  if (!params_.learn) return false;
  if (!std::isfinite(speed_rpm) || !std::isfinite(oil_temp_c) || !std::isfinite(friction_nm) ||
      !(friction_nm > 0.0)) {
    ++n_rejected_;
    return false;
  }
  // Outlier rejection (one bad input must not collapse the idle friction): once an idle level is
  // established (learned or imported), an observation farther than idle_outlier_frac from it is rejected.
  const double current = this->friction_nm(speed_rpm, oil_temp_c);
  const bool established = n_idle_ + idle_prior_n_ >= static_cast<std::uint64_t>(kIdlePriorObservations / 2);
  if (established && std::fabs(friction_nm - current) > params_.idle_outlier_frac * std::fabs(current)) {
    ++n_rejected_;
    return false;
  }
  ++n_idle_;
  if (scale_prior && level_active()) update_level(speed_rpm, oil_temp_c, friction_nm, obs_sd_nm);
  if (params_.learn_at_idle) {
    // Local correction: running mean of (observed − law) over the idle observations (gain 1/n, floor 0.1),
    // bounded to ±idle_max_correction_frac of the law at idle.
    const double g = std::max(0.1, 1.0 / static_cast<double>(n_idle_ + idle_prior_n_));
    idle_rpm_ = idle_rpm_ > 0.0 ? idle_rpm_ + g * (speed_rpm - idle_rpm_) : speed_rpm;
    // Bounded so that idle friction stays within ±idle_max_correction_frac of the unscaled law (with the
    // prior level: level and correction together).
    const double law = law_nm(speed_rpm, oil_temp_c);
    const double law0 = std::fabs(law / prior_level());
    const double f = params_.idle_max_correction_frac;
    idle_corr_nm_ = std::clamp(idle_corr_nm_ + g * ((friction_nm - law) - idle_corr_nm_),
                               std::min(0.0, (1.0 - f) * law0 - law), std::max(0.0, (1.0 + f) * law0 - law));
  }
  const double ln = std::log(friction_nm);
  if (!have_idle_ref_) {
    have_idle_ref_ = true;
    idle_ref_oil_c_ = oil_temp_c;
    idle_ref_ln_ = ln;
    return true;
  }
  // EN-30..33: Δ ln T_fric = C4 Δt_oil. Only informative once the oil temperature moved.
  const double dt = oil_temp_c - idle_ref_oil_c_;
  if (std::fabs(dt) < 2.0) {
    // Same temperature: refine the reference level (slow average).
    idle_ref_ln_ += 0.1 * (ln - idle_ref_ln_);
    return true;
  }
  const double y = ln - idle_ref_ln_;
  const double r = 1e-4;  // variance of Δ ln T (≈ 1 % noise on an averaged idle friction)
  const double k = p4_ * dt / (r + dt * p4_ * dt);
  c4_ += k * (y - c4_ * dt);
  p4_ = (1.0 - k * dt) * p4_ + 1e-10;
  idle_ref_oil_c_ = oil_temp_c;
  idle_ref_ln_ = ln;
  return true;
}

double FrictionLearner::oil_factor(double oil_temp_c) const noexcept {
  const double a = c4_ * oil_temp_c;
  if (a != oil_exp_arg_) {  // also NaN: computed every time
    oil_exp_arg_ = a;
    oil_exp_ = std::exp(a);
  }
  return oil_exp_;
}

double FrictionLearner::law_nm(double speed_rpm, double oil_temp_c) const noexcept {
  const double nk = speed_rpm / kS2;
  return prior_level() * params_.sign * oil_factor(oil_temp_c) *
         (theta_[0] + theta_[1] * nk + theta_[2] * nk * nk);
}

double FrictionLearner::friction_nm(double speed_rpm, double oil_temp_c) const noexcept {
  double f = law_nm(speed_rpm, oil_temp_c);
  if (idle_rpm_ > 0.0 && speed_rpm < params_.idle_fade_rpm) {
    const double span = params_.idle_fade_rpm - idle_rpm_;
    const double w =
        speed_rpm <= idle_rpm_ || !(span > 0.0) ? 1.0 : (params_.idle_fade_rpm - speed_rpm) / span;
    f += w * idle_corr_nm_;
  }
  return f;
}

std::array<double, 4> FrictionLearner::coefficients() const noexcept {
  return {theta_[0], theta_[1] / kS2, theta_[2] / kS3, c4_};
}

bool FrictionLearner::import_coefficients(const std::array<double, 4>& c) noexcept {
  if (!finite4(c)) return false;
  base_ = c;
  reset();
  imported_ = true;
  return true;
}

bool FrictionLearner::import_idle_correction(double correction_nm, double idle_rpm) noexcept {
  if (!std::isfinite(correction_nm) || !std::isfinite(idle_rpm) || !(idle_rpm > 0.0)) return false;
  idle_corr_nm_ = correction_nm;
  idle_rpm_ = idle_rpm;
  idle_prior_n_ = kIdlePriorObservations;
  return true;
}

bool FrictionLearner::import_motoring_residual_scale(double sd_nm, std::uint32_t n) noexcept {
  if (!std::isfinite(sd_nm) || !(sd_nm > 0.0)) return false;
  cover_.sd = std::max(sd_nm, params_.residual_sd_floor_nm);
  cover_.n = n;
  return true;
}

bool FrictionLearner::import_reference_sd(double sd_nm) noexcept {
  if (!std::isfinite(sd_nm) || sd_nm < 0.0) return false;
  ref_sd_nm_ = sd_nm;
  return true;
}

bool FrictionLearner::import_partial(std::uint64_t n) noexcept {
  if (!imported_ || n >= static_cast<std::uint64_t>(params_.min_observations)) return false;
  partial_ = true;
  n_motoring_ = n;
  return true;
}

Health FrictionLearner::health() const noexcept {
  if (!params_.learn || (imported_ && !partial_)) return Health::kValid;
  return n_motoring_ >= static_cast<std::uint64_t>(params_.min_observations) ? Health::kValid
                                                                             : Health::kNotConverged;
}

}  // namespace torqued
