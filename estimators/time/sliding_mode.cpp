#include "sliding_mode.hpp"

#include <cmath>

namespace torqued {

SlidingMode::SlidingMode(const SlidingModeParams& params, double inertia_kgm2, double step_s) noexcept
    : params_(params), inertia_kgm2_(inertia_kgm2) {
  out_f_.configure(params_.k_s, step_s);
  reset();
}

void SlidingMode::reset() noexcept {
  omega_hat_ = 0.0;
  out_f_.reset(0.0);
  primed_ = false;
  running_s_ = 0.0;
  estimate_ = TorqueEstimate{};
}

void SlidingMode::update(const TimeSample& s) noexcept {
  if (!accept_time_sample(s, /*need_maf=*/false, estimate_, primed_)) {
    running_s_ = 0.0;
    return;
  }
  if (!primed_) {
    omega_hat_ = s.speed_rad_s;
    out_f_.reset(s.load_torque_nm);  // steady-state start: τ_e = τ_l
    primed_ = true;
  }
  out_f_.set_step(s.dt_s);
  const double e = s.speed_rad_s - omega_hat_;
  const double sw = e > 0.0 ? params_.lambda1_nm : (e < 0.0 ? -params_.lambda1_nm : 0.0);  // λ1 sign(ω − ω̂)
  omega_hat_ += s.dt_s / inertia_kgm2_ * (sw - s.load_torque_nm);  // Na-35, exact for held inputs
  const double torque = out_f_.update(sw);                         // Na-21
  if (!std::isfinite(torque) || !std::isfinite(omega_hat_)) {
    reset();
    estimate_.t_ns = s.t_ns;
    estimate_.health = Health::kNumerical;
    return;
  }
  running_s_ += s.dt_s;
  estimate_.torque_nm = torque;
  estimate_.health = running_s_ >= 5.0 * params_.k_s ? Health::kValid : Health::kNotConverged;
}

}  // namespace torqued
