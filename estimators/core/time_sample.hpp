#pragma once
// Input of the time-triggered estimators of Na et al. (docs/equations.md §1): one pipeline step, SI units,
// each input with a status so an estimator can say why it holds (stale vs invalid).
#include <cmath>
#include <cstdint>

#include "estimate.hpp"

namespace torqued {

enum class InputStatus : std::uint8_t {
  kOk = 0,
  kStale = 1,    ///< no fresh value within its time-out (CAN lost, engine stopped)
  kInvalid = 2,  ///< rejected by the source (NaN, out of range, decoder not synced)
};

/// One step of the time-triggered pipeline (Na-8: J ω̇ = τ_e − τ_l).
struct TimeSample {
  std::int64_t t_ns = 0;        ///< time of this step on the edge clock (ns)
  double dt_s = 0.001;          ///< step since the previous sample (s); filters are exact for any dt > 0
  double speed_rad_s = 0.0;     ///< mean crank speed ω (cycle- or segment-averaged) (rad/s)
  double load_torque_nm = 0.0;  ///< measured load torque τ_l (dyno / e-machine) (N m)
  double maf_kg_s = 0.0;        ///< air mass flow ṁ_air (kg/s); only the adaptive estimator uses it
  InputStatus speed = InputStatus::kInvalid;
  InputStatus load = InputStatus::kInvalid;
  InputStatus maf = InputStatus::kInvalid;
};

/// Why a sample cannot be used, as a Health code: kValid when every needed input is OK and finite.
/// Invalid (or NaN, or a non-positive step) wins over stale. Real-time safe.
[[nodiscard]] inline Health check_time_sample(const TimeSample& s, bool need_maf) noexcept {
  bool invalid = !(s.dt_s > 0.0) || !std::isfinite(s.dt_s);
  bool stale = false;
  auto check = [&](InputStatus st, double v) {
    if (st == InputStatus::kInvalid || (st == InputStatus::kOk && !std::isfinite(v))) invalid = true;
    if (st == InputStatus::kStale) stale = true;
  };
  check(s.speed, s.speed_rad_s);
  check(s.load, s.load_torque_nm);
  if (need_maf) check(s.maf, s.maf_kg_s);
  if (invalid) return Health::kInvalidInput;
  if (stale) return Health::kStaleInput;
  return Health::kValid;
}

/// The common start of a time-triggered estimator's update: stamps `est` with the sample's time and checks
/// the sample (check_time_sample). A bad one is not used: `est.health` says why (its torque held from the
/// last good step) and `primed` is cleared, so the estimator restarts from the next good sample (its filter
/// history is no longer current). Returns whether the sample may be used. Real-time safe.
[[nodiscard]] inline bool accept_time_sample(const TimeSample& s, bool need_maf, TorqueEstimate& est,
                                             bool& primed) noexcept {
  est.t_ns = s.t_ns;
  const Health input = check_time_sample(s, need_maf);
  if (input == Health::kValid) return true;
  est.health = input;
  primed = false;
  return false;
}

}  // namespace torqued
