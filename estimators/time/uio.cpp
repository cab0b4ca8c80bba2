#include "uio.hpp"

#include <cmath>

namespace torqued {

namespace {
constexpr double kSettleTimeConstants = 5.0;  ///< e^-5 < 1 %: initial/restart transient of Na-17 has decayed
}

Uio::Uio(const UioParams& params, double inertia_kgm2, double step_s) noexcept
    : params_(params), inertia_kgm2_(inertia_kgm2), step_s_(step_s) {
  omega_f_.configure(params_.k_s, step_s_);
  load_f_.configure(params_.k_s, step_s_);
  reset();
}

void Uio::reset() noexcept {
  omega_f_.reset(0.0);
  load_f_.reset(0.0);
  primed_ = false;
  running_s_ = 0.0;
  estimate_ = TorqueEstimate{};
}

void Uio::update(const TimeSample& s) noexcept {
  if (!accept_time_sample(s, /*need_maf=*/false, estimate_, primed_)) {
    running_s_ = 0.0;
    return;
  }
  if (!primed_) {
    // Start on the manifold of a steady state (ω_f = ω, τ_lf = τ_l) instead of Na's zero start.
    omega_f_.reset(s.speed_rad_s);
    load_f_.reset(s.load_torque_nm);
    primed_ = true;
  }
  omega_f_.set_step(s.dt_s);
  load_f_.set_step(s.dt_s);
  // Na-14 with the filter states at t_n (inputs up to t_{n-1}); then advance the filters with the held
  // inputs.
  const double torque =
      inertia_kgm2_ * omega_f_.gain_per_s() * (s.speed_rad_s - omega_f_.state()) + load_f_.state();
  omega_f_.update(s.speed_rad_s);
  load_f_.update(s.load_torque_nm);
  if (!std::isfinite(torque) || !std::isfinite(omega_f_.state()) || !std::isfinite(load_f_.state())) {
    reset();
    estimate_.t_ns = s.t_ns;
    estimate_.health = Health::kNumerical;
    return;
  }
  running_s_ += s.dt_s;
  estimate_.torque_nm = torque;
  estimate_.uncertainty = 0.0;
  estimate_.health =
      running_s_ >= kSettleTimeConstants * params_.k_s ? Health::kValid : Health::kNotConverged;
}

}  // namespace torqued
