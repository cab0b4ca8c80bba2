#pragma once
// Analytic crankshaft plant for the time-triggered estimator tests: J ω̇ = τ_e(t) − τ_l(t) (Na-8) with
// closed-form ω(t) for constant, ramp and sinusoidal torques, sampled exactly at the estimator step.
#include <cmath>
#include <cstdint>

#include "time_sample.hpp"

namespace torqued::test {

inline TimeSample make_sample(double t_s, double dt_s, double speed, double load, double maf = 0.02) {
  TimeSample s;
  s.t_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
  s.dt_s = dt_s;
  s.speed_rad_s = speed;
  s.load_torque_nm = load;
  s.maf_kg_s = maf;
  s.speed = s.load = s.maf = InputStatus::kOk;
  return s;
}

/// τ_e = tau0 + rate·t + amp·sin(w t), τ_l = load (constant), ω(0) = omega0.
struct AnalyticPlant {
  double inertia = 0.14;
  double omega0 = 200.0;
  double tau0 = 80.0;
  double rate = 0.0;  ///< N m/s
  double amp = 0.0;   ///< N m
  double w = 0.0;     ///< rad/s
  double load = 50.0;

  [[nodiscard]] double torque(double t) const { return tau0 + rate * t + amp * std::sin(w * t); }
  [[nodiscard]] double speed(double t) const {
    double integral = (tau0 - load) * t + 0.5 * rate * t * t;
    if (w != 0.0) integral += amp * (1.0 - std::cos(w * t)) / w;
    return omega0 + integral / inertia;
  }
};

}  // namespace torqued::test
