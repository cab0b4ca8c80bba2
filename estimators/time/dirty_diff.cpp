#include "dirty_diff.hpp"

#include <cmath>

namespace torqued {

DirtyDiff::DirtyDiff(const DirtyDiffParams& params, double inertia_kgm2, double step_s) noexcept
    : params_(params), inertia_kgm2_(inertia_kgm2) {
  omega_f_.configure(params_.k_s, step_s);
  reset();
}

void DirtyDiff::reset() noexcept {
  omega_f_.reset(0.0);
  primed_ = false;
  running_s_ = 0.0;
  estimate_ = TorqueEstimate{};
}

void DirtyDiff::update(const TimeSample& s) noexcept {
  if (!accept_time_sample(s, /*need_maf=*/false, estimate_, primed_)) {
    running_s_ = 0.0;
    return;
  }
  if (!primed_) {
    omega_f_.reset(s.speed_rad_s);
    primed_ = true;
  }
  omega_f_.set_step(s.dt_s);
  // Na-24: dirty derivative of ω times J, plus the raw load torque.
  const double torque =
      inertia_kgm2_ * omega_f_.gain_per_s() * (s.speed_rad_s - omega_f_.state()) + s.load_torque_nm;
  omega_f_.update(s.speed_rad_s);
  if (!std::isfinite(torque) || !std::isfinite(omega_f_.state())) {
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
