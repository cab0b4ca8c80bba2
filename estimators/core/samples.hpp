#pragma once
// Inputs of the estimators, in SI units, decoupled from io/ (estimators/ depends on nothing but Eigen).
// The daemon converts io::ToothEvent and signal-store values into these.
#include <cmath>
#include <cstdint>

#include "estimate.hpp"

namespace torqued {

/// One crank tooth, as the angle pipeline sees it (docs/equations.md §2: sampled every Δα).
struct ToothSample {
  std::int64_t t_ns = 0;  ///< edge time (ns)
  std::int32_t tooth =
      0;  ///< index within the 720° cycle, 0 .. samples_per_cycle-1 (0 = first tooth after gap, cam phase 0)
  double angle_rad = 0.0;  ///< edge angle within 720° measured from the first tooth after the gap (rad)
  double width_rad =
      0.0;  ///< true angular width of the period that ends at this edge (rad), incl. learned correction
  double dt_s = 0.0;    ///< duration of that period (s)
  bool synced = false;  ///< decoder synced with 720° phase known; estimators hold when false
};

/// Shared input check of the per-tooth estimators: kNoSync when the decoder is not synced, kInvalidInput for
/// a non-positive or non-finite period/width, a speed width/period that is not finite (a subnormal period),
/// or a tooth index outside [0, samples_per_cycle), else kValid.
[[nodiscard]] inline Health check_tooth_sample(const ToothSample& s, int samples_per_cycle) noexcept {
  if (!s.synced) return Health::kNoSync;
  if (!(s.dt_s > 0.0) || !(s.width_rad > 0.0) || !std::isfinite(s.dt_s) || !std::isfinite(s.width_rad) ||
      !std::isfinite(s.width_rad / s.dt_s) || s.tooth < 0 || s.tooth >= samples_per_cycle) {
    return Health::kInvalidInput;
  }
  return Health::kValid;
}

/// Slow quantities from CAN (signal store), SI units, each with validity (stale or rejected -> false).
struct EngineSignals {
  std::int64_t t_ns = 0;  ///< time of the newest contributing frame (ns)
  double map_pa = 0.0;
  bool map_valid = false;  ///< intake manifold pressure
  double maf_kg_s = 0.0;
  bool maf_valid = false;  ///< air mass flow
  double intake_temp_k = 0.0;
  bool intake_temp_valid = false;
  double oil_temp_c = 0.0;
  bool oil_temp_valid = false;  ///< °C (friction law EN-24 uses °C)
  double throttle_pct = 0.0;
  bool throttle_valid = false;
  double lambda = 1.0;
  bool lambda_valid = false;
  double spark_advance_deg = 0.0;
  bool spark_valid = false;
  double fuel_mass_kg = 0.0;
  bool fuel_mass_valid = false;  ///< fuel per injection per cylinder
  bool fuel_cutoff = false;
  bool fuel_cutoff_valid = false;
  double load_torque_nm = 0.0;
  bool load_torque_valid = false;  ///< dyno / driveline load torque
  double em_torque_nm = 0.0;
  bool em_torque_valid = false;  ///< electric machine torque as on CAN (e_machine.hpp)
  bool em_sole_load = false;
  bool em_sole_load_valid = false;  ///< the machine is the only load (load_reference.hpp)
  bool neutral = false;
  bool neutral_valid = false;  ///< clutch open / neutral (load_reference.hpp)
};

}  // namespace torqued
