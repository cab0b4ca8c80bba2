#pragma once
// Physical range of an engine's torque, for the project's subscribers (torque-echo, torque-dash): a sample
// outside it (a foreign plain-DDS writer's fused 1e9 N m with quality 0, a corrupt peer) is flagged, not
// shown as if it were a reading. Bounds from the configured geometry only:
//  - cycle and segment means (EngineTorque; the per-cycle methods of EstimatorTorque): |T| ≤ MEP·V_d/(4π)
//    (four-stroke: one power stroke per cylinder per 720°) with MEP = 50 bar, above the brake MEP of any
//    production engine (the most boosted diesels reach about 30 bar, Heywood, Internal Combustion Engine
//    Fundamentals, 2nd ed., §2.7) and the bound of a learned friction MEP (learned/state_store.hpp);
//  - instantaneous (the in-cycle and time-domain methods): |T| ≤ n_cyl · p_max · A_piston · r_crank with
//  p_max = 300 bar,
//    above the peak firing pressure of heavy-duty diesels (about 250 bar): every cylinder pushing its whole
//    peak force on the full crank arm.
// A bound of 0 (no engine configured) checks finiteness only.
#include <cmath>
#include <cstdint>

#include "methods.hpp"
#include "topics.hpp"

namespace torqued::dds {

struct TorqueRange {
  double mean_nm = 0.0;     ///< |mean torque| bound (N m); 0 = unknown
  double instant_nm = 0.0;  ///< |instantaneous torque| bound (N m); 0 = unknown
};

inline TorqueRange torque_range(int cylinders, double bore_m, double stroke_m) noexcept {
  constexpr double kPi = 3.14159265358979323846;
  constexpr double kMaxMepPa = 50e5, kMaxPeakPa = 300e5;
  if (!(cylinders > 0 && bore_m > 0.0 && stroke_m > 0.0)) return {};
  const double area = kPi / 4.0 * bore_m * bore_m;
  const double vd = cylinders * area * stroke_m;
  return {kMaxMepPa * vd / (4.0 * kPi), cylinders * kMaxPeakPa * area * 0.5 * stroke_m};
}

inline bool torque_in_range(double v, double bound) noexcept {
  return std::isfinite(v) && (bound <= 0.0 || std::abs(v) <= bound);
}

/// Every torque of an EngineTorque sample (brake, indicated, friction, load, fused) within the mean bound.
inline bool in_range(const torque_EngineTorque& s, const TorqueRange& r) noexcept {
  for (const double v : {s.brake_nm, s.indicated_nm, s.friction_nm, s.load_nm, s.fused_nm})
    if (!torque_in_range(v, r.mean_nm)) return false;
  return true;
}

/// An EstimatorTorque value within the bound of its method: per segment/cycle methods the mean bound, the
/// others (in-cycle, time domain, unknown ids) the instantaneous one.
inline bool in_range(const torque_EstimatorTorque& s, const TorqueRange& r) noexcept {
  const MethodInfo* m = method_info(s.method);
  const bool mean = m != nullptr && m->domain == MethodDomain::kPerCycle;
  return torque_in_range(s.value_nm, mean ? r.mean_nm : r.instant_nm);
}

}  // namespace torqued::dds
