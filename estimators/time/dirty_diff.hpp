#pragma once
// Dirty-differentiation torque estimator, Na et al. 2017 eq. (23)-(24); kept for comparison with the UIO.
//   τ̂_e = J s/(ks+1)[ω] + τ_l = J (ω − ω_f)/k + τ_l     (load NOT filtered, Na-24)
// Its error depends on ω̈ and on the raw load noise (Na Lemma 3/5), which is why the UIO beats it.
// Discretisation: exact ZOH filter, 1/k → α/T as in uio.hpp.
#include "estimate.hpp"
#include "first_order_filter.hpp"
#include "params.hpp"
#include "time_sample.hpp"

namespace torqued {

class DirtyDiff {
 public:
  DirtyDiff(const DirtyDiffParams& params, double inertia_kgm2, double step_s = 0.001) noexcept;
  void reset() noexcept;
  /// One step; stale/invalid input holds the estimate with the reason. Real-time safe.
  void update(const TimeSample& s) noexcept;
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return estimate_; }

 private:
  DirtyDiffParams params_;
  double inertia_kgm2_;
  FirstOrderFilter<double> omega_f_;
  bool primed_ = false;
  double running_s_ = 0.0;
  TorqueEstimate estimate_{};
};

}  // namespace torqued
