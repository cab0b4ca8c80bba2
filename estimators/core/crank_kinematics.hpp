#pragma once
// Slider-crank kinematics (docs/equations.md §0; Energies 2019 eq. (EN-5)..(EN-9), Chauvin TV-KF eq. (CK-1)).
// Scalar functions are real-time safe (no allocation, noexcept). `KinematicsTable` precomputes per-angle
// values for a wheel at construction so that the per-tooth path never calls trigonometry.
#include <cstddef>
#include <vector>

#include "engine_geometry.hpp"

namespace torqued {

class CrankKinematics {
 public:
  explicit CrankKinematics(const EngineGeometry& geometry) noexcept;

  /// Piston travel from TDC s(θ) (m); θ crank angle after that cylinder's TDC (rad).
  [[nodiscard]] double travel(double theta) const noexcept;
  /// f(θ) = (ds/dθ)/R (-).
  [[nodiscard]] double f(double theta) const noexcept;
  /// g(θ) = f'(θ) (-). docs/equations.md §0 gives the corrected form of (EN-5).
  [[nodiscard]] double g(double theta) const noexcept;
  /// Cylinder volume V(θ) = V_c + A s(θ) (m^3) (EN-8).
  [[nodiscard]] double volume(double theta) const noexcept;
  /// dV/dθ = A R f(θ) (m^3/rad).
  [[nodiscard]] double dvolume(double theta) const noexcept { return area_ * r_ * f(theta); }
  /// volume(θ) and dvolume(θ) together, sharing sin θ and the root (the same values bit for bit; start-up
  /// tables call both at every angle).
  void volume_and_dvolume(double theta, double& volume_m3, double& dvolume_m3_rad) const noexcept;
  /// Firing phase φ_j of cylinder `cyl` (1-based) in rad within [0, 4π): from the firing order position.
  [[nodiscard]] double phase(int cyl) const noexcept;
  /// Crank angle relative to cylinder `cyl`'s firing TDC, wrapped to [0, 4π). `theta720` is angle after cyl-1
  /// TDC.
  [[nodiscard]] double local_angle(double theta720, int cyl) const noexcept;
  /// Gas torque of one cylinder at pressure p (Pa): (p − p_cc) A R f(θ − φ_j) (N m) (EN-9).
  [[nodiscard]] double gas_torque(double theta720, int cyl, double p_pa) const noexcept;
  /// Total inertia J(θ) = J_rot + m_osc Σ R² f_j² (kg m^2) (CK-1).
  [[nodiscard]] double inertia(double theta720) const noexcept;
  /// ½ J'(θ) = m_osc Σ R² f_j g_j (kg m^2/rad) (CK-1).
  [[nodiscard]] double half_dinertia(double theta720) const noexcept;
  /// Reciprocating (mass) torque (EN-5/6): (J − J_rot) θ̈ + ½ J' θ̇² (N m).
  [[nodiscard]] double mass_torque(double theta720, double omega, double alpha) const noexcept;

  [[nodiscard]] double piston_area_m2() const noexcept { return area_; }
  [[nodiscard]] double clearance_volume_m3() const noexcept { return vc_; }
  [[nodiscard]] double displacement_m3() const noexcept { return area_ * 2.0 * r_ * geometry_.cylinders; }
  [[nodiscard]] const EngineGeometry& geometry() const noexcept { return geometry_; }

 private:
  EngineGeometry geometry_;
  double r_;                                   ///< crank radius (m)
  double lambda_;                              ///< R/l (-)
  double area_;                                ///< piston area (m^2)
  double vc_;                                  ///< clearance volume (m^3)
  std::array<double, kMaxCylinders> phase_{};  ///< φ_j by cylinder index (0-based) (rad)
};

/// Per-sample table over one 720° cycle at `samples` equally spaced angles (e.g. 120 for a 60-2 wheel's 6°).
/// Built once at start-up (allocates then, never after).
class KinematicsTable {
 public:
  KinematicsTable(const CrankKinematics& kin, int samples);
  [[nodiscard]] int samples() const noexcept { return samples_; }
  [[nodiscard]] double step_rad() const noexcept { return step_; }
  [[nodiscard]] double inertia(int n) const noexcept { return j_[static_cast<std::size_t>(n)]; }
  [[nodiscard]] double half_dinertia(int n) const noexcept { return hdj_[static_cast<std::size_t>(n)]; }
  /// A R f(θ_n − φ_j) for cylinder index c (0-based): gas torque per Pa.
  [[nodiscard]] double torque_per_pa(int n, int c) const noexcept {
    return tpp_[static_cast<std::size_t>(n * kMaxCylinders + c)];
  }

 private:
  int samples_;
  double step_;
  std::vector<double> j_, hdj_, tpp_;
};

}  // namespace torqued
