#pragma once
// Indicated torque by an extended state observer (Energies 2019 eq. (EN-16)..(EN-23)).
//   W_ind = m_f q_LHV E_ff per cylinder and cycle (EN-16), E_ff = (1 − r_c^{1−κ}) · min(1, λ) · η (EN-17),
//   where the paper's ignition and heat-transfer efficiencies η_ign·η_ig,ch are lumped into
//   `eso_base_efficiency` (their maps are engine-specific calibrations the paper does not print); the ESO's
//   extended state ΔE_ff absorbs the rest. Mean indicated torque T_ind = (E_ff + ΔE_ff) Q_mass with Q_mass =
//   n_cyl m_f q_LHV / 4π (4-stroke) (N m).
// The paper writes the observer in time on the speed (EN-18..20). Here it runs in the ANGLE domain on the
// kinetic energy, which is the same crank balance without the ½J'θ̇² term or a mean inertia (CF-2):
//   dz1/dθ = (E_ff + z2) Q_mass − T_fric − T_load + β1 (y − z1),   dz2/dθ = β2 (y − z1),   y = ½Jθ̇² at each
//   boundary.
// Discretised per segment (Δθ) with both error poles at p = e^{−ω0 Δt} (bandwidth tuning (s + ω0)², EN-23):
//   l1 = 2 − 2p,  l2 = (1 − p)² / (Δθ Q_mass).
// The per-segment z2 carries the cylinder-to-cylinder ripple of the energy (imbalance, boundary phase), so
// the reported torque is the mean of (E_ff + z2) Q_mass over the last n_cyl segments (one cycle).
#include <array>
#include <cstdint>

#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "params.hpp"

namespace torqued {

struct EsoInput {
  std::int64_t t_ns = 0;
  double ke_j = 0.0;          ///< measured ½Jθ̇² at the boundary (J)
  double segment_rad = 0.0;   ///< crank angle since the previous update (rad)
  double segment_dt_s = 0.0;  ///< time since the previous update (s)
  double fuel_kg = 0.0;       ///< fuel per injection per cylinder (kg)
  double lambda = 1.0;        ///< air/fuel equivalence (-)
  double friction_nm = 0.0;   ///< friction over the segment (N m)
  double load_nm = 0.0;       ///< load over the segment (N m)
  bool valid = false;         ///< all of the above known and the segment contiguous
};

class IndicatedEso {
 public:
  IndicatedEso(const EngineGeometry& engine, const EnergiesParams& params) noexcept;
  void reset() noexcept;
  /// One segment step. Real-time safe. Returns false (and resets the energy state) on invalid input.
  bool update(const EsoInput& in) noexcept;
  /// Mean indicated torque (N m) with health: kNotConverged during the first ~3/ω0 seconds.
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return est_; }
  [[nodiscard]] double efficiency_correction() const noexcept { return z2_; }
  [[nodiscard]] double model_efficiency(double lambda) const noexcept;

 private:
  EngineGeometry engine_;
  EnergiesParams params_;
  double eta_thermo_ = 0.0;
  double z1_ = 0.0, z2_ = 0.0;
  bool init_ = false;
  double run_s_ = 0.0;
  std::array<double, kMaxCylinders> recent_{};  ///< last n_cyl segment torques (N m)
  int recent_n_ = 0, recent_i_ = 0;
  TorqueEstimate est_;
};

}  // namespace torqued
