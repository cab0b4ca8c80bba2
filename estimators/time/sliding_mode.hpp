#pragma once
// Sliding-mode torque estimator (equivalent control), Na et al. 2017 eq. (19)-(21), (35); for comparison.
//   J dω̂/dt = −τ_l + λ1 sign(ω − ω̂)            (Na-19/35), λ1 > sup|τ_e|
//   τ̂_e = 1/(ks+1) [λ1 sign(ω − ω̂)]             (Na-21)
// Discretisation: the right-hand side is constant over a step (inputs held, sign evaluated at t_n), so the
// forward step ω̂[n+1] = ω̂[n] + T/J (−τ_l + λ1 sign) is the exact solution over that step; the output filter
// is the exact ZOH low-pass. In discrete time the observer chatters with amplitude λ1·T/J around ω (1 ms,
// λ1 = 150 N m, J = 0.14 kg m²: ±1.1 rad/s): that is the chattering Na's comparison shows.
#include "estimate.hpp"
#include "first_order_filter.hpp"
#include "params.hpp"
#include "time_sample.hpp"

namespace torqued {

class SlidingMode {
 public:
  SlidingMode(const SlidingModeParams& params, double inertia_kgm2, double step_s = 0.001) noexcept;
  void reset() noexcept;
  /// One step; stale/invalid input holds the estimate with the reason. Real-time safe.
  void update(const TimeSample& s) noexcept;
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return estimate_; }
  [[nodiscard]] double observed_speed_rad_s() const noexcept { return omega_hat_; }

 private:
  SlidingModeParams params_;
  double inertia_kgm2_;
  double omega_hat_ = 0.0;
  FirstOrderFilter<double> out_f_;
  bool primed_ = false;
  double running_s_ = 0.0;
  TorqueEstimate estimate_{};
};

}  // namespace torqued
