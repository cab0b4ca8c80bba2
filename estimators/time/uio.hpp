#pragma once
// Unknown-input observer of the effective engine torque, Na et al. 2017 eq. (9), (14).
//   k ω̇_f = −ω_f + ω,  k τ̇_lf = −τ_lf + τ_l          (Na-9)
//   τ̂_e = J (ω − ω_f)/k + τ_lf                        (Na-14)
// Error dynamics ε̇ = −ε/k + τ̇_e (Na-17): a constant torque is recovered exactly, a ramp lags by k·τ̇_e.
// Discretisation: exact ZOH of both filters (first_order_filter.hpp) and 1/k replaced by its exact discrete
// counterpart α/T, so the discrete estimate equals J·Δω_f/T + τ_lf (discrete form of Na-15). With that choice
// a constant torque is exact for any step and the ramp lag is r·(T/α − T/2) = r·(k + T²/(12k) + …).
#include "estimate.hpp"
#include "first_order_filter.hpp"
#include "params.hpp"
#include "time_sample.hpp"

namespace torqued {

class Uio {
 public:
  /// inertia_kgm2: J of Na-8 (mean crankshaft-side inertia), > 0. step_s: nominal step (exact for any dt).
  Uio(const UioParams& params, double inertia_kgm2, double step_s = 0.001) noexcept;

  /// Filters to zero and the convergence clock restarted (Na-9: ω_f(0) = τ_lf(0) = 0 unless primed).
  void reset() noexcept;
  /// One step. On a stale/invalid input the state and estimate are held and health says why. Real-time safe.
  void update(const TimeSample& s) noexcept;
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return estimate_; }

  [[nodiscard]] double speed_filtered_rad_s() const noexcept { return omega_f_.state(); }
  [[nodiscard]] double load_filtered_nm() const noexcept { return load_f_.state(); }

 private:
  UioParams params_;
  double inertia_kgm2_;
  double step_s_;
  FirstOrderFilter<double> omega_f_;
  FirstOrderFilter<double> load_f_;
  bool primed_ = false;  ///< filters start at the first sample (avoids the zero-start transient of Na §VIII)
  double running_s_ = 0.0;  ///< time since (re)start with good inputs (s)
  TorqueEstimate estimate_{};
};

}  // namespace torqued
