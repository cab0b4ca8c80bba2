#pragma once
// A claimed 1σ calibrated on coverage ("a claimed 1σ covers the error about 68 % of the time").
// The residuals a learner sees are not Gaussian: a model that fits most operating points to a fraction of a
// N m and a few by several N m has an RMS that is covered 80-100 % of the time. The scale reported here is
// instead the running 68.27th percentile of |residual|, so |error| ≤ sd on 68 % of the residuals whatever
// their shape. Stochastic approximation in the log domain (Robbins-Monro on the quantile of log|e|):
//   log sd += g · K · (1[|e| > sd] − (1 − 0.6827)),  g = max(1/n, gain_min)
// which is at rest when P(|e| > sd) = 31.73 %. K = 2 because the density of log|e| at its 68th percentile
// is ≈ 0.5 for a Gaussian (a step of 1/n converges when K·density ≥ ½). A residual of 0 or a non-finite one
// is ignored. Real-time safe: no allocation, one exp().
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace torqued {

struct CoverageScale {
  static constexpr double kCoverage = 0.68268949213708585;  ///< P(|z| ≤ 1) of a normal variable
  static constexpr double kGain = 2.0;                      ///< K above

  double sd = 0.0;      ///< current scale (unit of the residual); 0 until `start` or the first residual
  std::uint32_t n = 0;  ///< residuals seen

  /// Start from a prior scale (kept until residuals arrive).
  void start(double prior_sd) noexcept {
    sd = prior_sd > 0.0 && std::isfinite(prior_sd) ? prior_sd : 0.0;
    n = 0;
  }
  /// observe(), starting from `prior_sd` when no scale is held yet (a learner's claimed σ before it
  /// measured).
  void observe_from(double prior_sd, double err, double gain_min, double floor) noexcept {
    if (!(sd > 0.0)) start(prior_sd);
    observe(err, gain_min, floor);
  }
  /// One residual `err`; `gain_min` floors the step 1/n (a long but finite memory); the scale stays ≥
  /// `floor`.
  void observe(double err, double gain_min, double floor) noexcept {
    const double a = std::fabs(err);
    if (!std::isfinite(a) || !(a > 0.0)) return;
    ++n;
    if (!(sd > 0.0)) {
      sd = std::max(a, floor);
      return;
    }
    const double g = std::max(1.0 / static_cast<double>(n), gain_min);
    const double step = a > sd ? kCoverage : -(1.0 - kCoverage);
    sd = std::max(floor, sd * std::exp(g * kGain * step));
  }
};

}  // namespace torqued
