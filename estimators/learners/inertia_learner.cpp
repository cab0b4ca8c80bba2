#include "inertia_learner.hpp"

#include <algorithm>
#include <cmath>

namespace torqued {

void InertiaLearner::reset() noexcept {
  const double s0 = params_.prior_rel_sd > 0.0 ? params_.prior_rel_sd : 1.0;
  info_ = 1.0 / (s0 * s0);
  sxy_ = info_ * 1.0;
  k_ = 1.0;
  imported_ = false;
  n_ = n_rejected_ = 0;
}

double InertiaLearner::scale_sd() const noexcept { return info_ > 0.0 ? 1.0 / std::sqrt(info_) : 0.0; }

bool InertiaLearner::observe(double x_nm, double y_nm) noexcept {
  if (!params_.learn || !std::isfinite(x_nm) || !std::isfinite(y_nm)) return false;
  if (std::fabs(x_nm) < params_.min_step_nm) return false;
  const double r2 = params_.obs_sd_nm * params_.obs_sd_nm;
  // Innovation gate: residual against the current k, with the spread of k itself.
  const double resid = y_nm - k_ * x_nm;
  const double resid_var = r2 + x_nm * x_nm / info_;
  if (resid * resid > params_.gate_sigma * params_.gate_sigma * resid_var) {
    ++n_rejected_;
    return false;
  }
  info_ += x_nm * x_nm / r2;
  sxy_ += x_nm * y_nm / r2;
  k_ = std::clamp(sxy_ / info_, params_.min_scale, params_.max_scale);
  ++n_;
  return true;
}

bool InertiaLearner::import_state(double scale, double information) noexcept {
  const double s0 = params_.prior_rel_sd > 0.0 ? params_.prior_rel_sd : 1.0;
  if (!std::isfinite(scale) || !std::isfinite(information) || scale < params_.min_scale ||
      scale > params_.max_scale || information < 1.0 / (s0 * s0) * (1.0 - 1e-9))
    return false;
  info_ = information;
  k_ = scale;
  sxy_ = scale * information;
  imported_ = true;
  return true;
}

}  // namespace torqued
