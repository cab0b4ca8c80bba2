#pragma once
// Crank-angle-domain engine model of the simulator (internal to torqued_sim): kinematics of every cylinder
// evaluated together (one sin/cos per cylinder), single-zone first-law cylinder pressure with Wiebe heat
// release, friction, and the crankshaft balance in energy form. docs/simulator.md §1-2, §4.
#include <array>

#include "engine_sim.hpp"

namespace torqued::sim {

/// One combustion event of one cylinder, from IVC to the end of blowdown.
struct CylinderEvent {
  bool active = false;
  double theta_tdc_rad = 0.0;  ///< wheel angle of this event's firing TDC (rad)
  double q_total_j = 0.0;      ///< heat released by the Wiebe function (J)
  double soc_rad = 0.0;        ///< start of combustion relative to TDC (rad), negative = before TDC
  int cycle = 0;               ///< output cycle of the firing TDC
  double peak_pa = 0.0;
};

/// Slow inputs held constant over one integration step.
struct HeldInputs {
  double t_load_nm = 0.0;
  double map_pa = 100000.0;
  double oil_temp_c = 90.0;
  double locked_omega_rad_s = 0.0;  ///< > 0: speed imposed (start-up phase); K follows ½ J ω²
};

/// Everything the truth needs at one angle.
struct ModelEval {
  double omega_rad_s = 0.0;
  double t_ind_nm = 0.0;
  std::array<double, kMaxCylinders> t_cyl_nm{};
  std::array<double, kMaxCylinders> p_pa{};
  double t_fric_nm = 0.0;
  double inertia_kgm2 = 0.0;
  double half_dinertia = 0.0;  ///< ½ J'(θ) (kg m²/rad)
};

class EngineModel {
 public:
  static constexpr int kStateSize = 2 + kMaxCylinders;  ///< [t (s), K = ½Jθ̇² (J), p_1..p_8 (Pa)]
  using State = std::array<double, kStateSize>;

  explicit EngineModel(const Scenario& scenario);

  /// dy/dθ at wheel angle θ_w (docs/equations.md §0 energy form (CF-2): dK/dθ = T_ind − T_fric − T_load;
  /// dt/dθ = 1/θ̇; first-law dp/dθ = ((γ−1)/V) dQ/dθ − γ (p/V) dV/dθ). Fills `ev` when non-null.
  void derivative(double theta_w, const State& y, const HeldInputs& in, State& dy,
                  ModelEval* ev) const noexcept;

  /// Wheel angle of cylinder c's (0-based) firing TDC with index 0.
  [[nodiscard]] double tdc_base_rad(int c) const noexcept { return tdc_base_[static_cast<std::size_t>(c)]; }
  /// Cylinder volume at angle ψ after that cylinder's firing TDC (m³).
  [[nodiscard]] double volume_m3(double psi) const noexcept;
  /// Friction (EN-27 with the paper's coefficients, sign corrected so that it is a positive loss; speed in
  /// rpm).
  [[nodiscard]] double friction_nm(double omega_rad_s, double oil_temp_c) const noexcept;

  [[nodiscard]] CylinderEvent& event(int c) noexcept { return events_[static_cast<std::size_t>(c)]; }
  [[nodiscard]] const CylinderEvent& event(int c) const noexcept {
    return events_[static_cast<std::size_t>(c)];
  }
  [[nodiscard]] int cylinders() const noexcept { return n_; }
  [[nodiscard]] double displacement_m3() const noexcept { return area_ * 2.0 * r_ * n_; }

 private:
  [[nodiscard]] double wiebe_dq(const CylinderEvent& e, double psi) const noexcept;
  int n_;
  EngineGeometry geo_;
  CombustionParams comb_;
  FrictionModel fric_;
  double r_, l_, lambda_, area_, vc_;
  double evo_rad_, bd_end_rad_, dur_rad_;
  std::array<double, kMaxCylinders> tdc_base_{}, sin_base_{}, cos_base_{};
  std::array<CylinderEvent, kMaxCylinders> events_{};
};

}  // namespace torqued::sim
