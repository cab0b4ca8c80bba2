#pragma once
// Mean-value air path of the simulator: isentropic throttle orifice + isothermal intake manifold filling +
// speed-density cylinder flow (Guzzella & Onder, "Introduction to Modeling and Control of IC Engine Systems",
// §2.3; Heywood App. C). docs/simulator.md §3.
#include "engine_sim.hpp"

namespace torqued::sim {

class AirPath {
 public:
  AirPath(const AirPathParams& air, const CombustionParams& comb, double displacement_m3,
          double intake_temp_k);

  /// Air mass flow through the throttle at opening u ∈ [0, 1] and manifold pressure p_m (kg/s).
  [[nodiscard]] double throttle_flow_kg_s(double u, double p_m_pa) const noexcept;
  /// Mean air flow into the cylinders: η_v p_m V_d ω / (4π R T_m) (kg/s).
  [[nodiscard]] double cylinder_flow_kg_s(double p_m_pa, double omega_rad_s) const noexcept;
  /// Throttle opening that balances the flows at manifold pressure p_target and speed ω (steady state).
  [[nodiscard]] double throttle_for_map(double p_target_pa, double omega_rad_s) const noexcept;
  /// Steady manifold pressure for opening u and speed ω (bisection).
  [[nodiscard]] double steady_map(double u, double omega_rad_s) const noexcept;
  /// Trapped air per cylinder and cycle at IVC pressure p_ivc: η_v p V_d,cyl / (R T_m) (kg).
  [[nodiscard]] double trapped_air_kg(double p_ivc_pa, int cylinders) const noexcept;

  void reset(double map_pa) noexcept { map_pa_ = map_pa; }
  /// Explicit Euler over dt: dp_m/dt = R T_m / V_m (ṁ_th − ṁ_cyl).
  void step(double u, double omega_rad_s, double dt_s) noexcept;
  [[nodiscard]] double map_pa() const noexcept { return map_pa_; }
  [[nodiscard]] double throttle_flow_now_kg_s() const noexcept { return mdot_th_; }

 private:
  [[nodiscard]] double area_m2(double u) const noexcept;
  AirPathParams air_;
  double vol_eff_;
  double displacement_m3_;
  double temp_k_;
  double area_max_m2_;
  double map_pa_ = 50000.0;
  double mdot_th_ = 0.0;
};

}  // namespace torqued::sim
