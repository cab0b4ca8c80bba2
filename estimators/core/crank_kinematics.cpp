#include "crank_kinematics.hpp"

#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
}  // namespace

CrankKinematics::CrankKinematics(const EngineGeometry& geometry) noexcept
    : geometry_(geometry),
      r_(geometry.crank_radius_m()),
      lambda_(r_ / geometry.rod_m),
      area_(std::numbers::pi * geometry.bore_m * geometry.bore_m / 4.0),
      vc_(area_ * 2.0 * r_ / (geometry.compression_ratio - 1.0)) {
  // 4-stroke: the cylinder at firing-order position m fires 4π·m/n after cylinder 1 (docs/equations.md §0).
  for (int m = 0; m < geometry.cylinders; ++m) {
    const int cyl = geometry.firing_order[static_cast<std::size_t>(m)];
    phase_[static_cast<std::size_t>(cyl - 1)] = kFourPi * m / geometry.cylinders;
  }
}

double CrankKinematics::travel(double theta) const noexcept {
  const double s = std::sin(theta);
  return r_ * (1.0 - std::cos(theta)) + geometry_.rod_m * (1.0 - std::sqrt(1.0 - lambda_ * lambda_ * s * s));
}

double CrankKinematics::f(double theta) const noexcept {
  const double s = std::sin(theta);
  const double root = std::sqrt(1.0 - lambda_ * lambda_ * s * s);
  return s + lambda_ * std::sin(2.0 * theta) / (2.0 * root);
}

double CrankKinematics::g(double theta) const noexcept {
  const double s = std::sin(theta);
  const double q = 1.0 - lambda_ * lambda_ * s * s;
  const double root = std::sqrt(q);
  const double s2 = std::sin(2.0 * theta);
  return std::cos(theta) + lambda_ * std::cos(2.0 * theta) / root +
         lambda_ * lambda_ * lambda_ * s2 * s2 / (4.0 * q * root);
}

double CrankKinematics::volume(double theta) const noexcept { return vc_ + area_ * travel(theta); }

void CrankKinematics::volume_and_dvolume(double theta, double& volume_m3,
                                         double& dvolume_m3_rad) const noexcept {
  const double s = std::sin(theta);
  const double root = std::sqrt(1.0 - lambda_ * lambda_ * s * s);  // the root of travel() and of f()
  volume_m3 = vc_ + area_ * (r_ * (1.0 - std::cos(theta)) + geometry_.rod_m * (1.0 - root));
  dvolume_m3_rad = area_ * r_ * (s + lambda_ * std::sin(2.0 * theta) / (2.0 * root));
}

double CrankKinematics::phase(int cyl) const noexcept { return phase_[static_cast<std::size_t>(cyl - 1)]; }

double CrankKinematics::local_angle(double theta720, int cyl) const noexcept {
  double a = std::fmod(theta720 - phase(cyl), kFourPi);
  if (a < 0.0) a += kFourPi;
  return a;
}

double CrankKinematics::gas_torque(double theta720, int cyl, double p_pa) const noexcept {
  return (p_pa - geometry_.crankcase_pressure_pa) * area_ * r_ * f(theta720 - phase(cyl));
}

double CrankKinematics::inertia(double theta720) const noexcept {
  double sum = 0.0;
  for (int c = 1; c <= geometry_.cylinders; ++c) {
    const double fj = f(theta720 - phase(c));
    sum += fj * fj;
  }
  return geometry_.j_rot_kgm2 + geometry_.m_osc_kg * r_ * r_ * sum;
}

double CrankKinematics::half_dinertia(double theta720) const noexcept {
  double sum = 0.0;
  for (int c = 1; c <= geometry_.cylinders; ++c) {
    const double a = theta720 - phase(c);
    sum += f(a) * g(a);
  }
  return geometry_.m_osc_kg * r_ * r_ * sum;
}

double CrankKinematics::mass_torque(double theta720, double omega, double alpha) const noexcept {
  return (inertia(theta720) - geometry_.j_rot_kgm2) * alpha + half_dinertia(theta720) * omega * omega;
}

KinematicsTable::KinematicsTable(const CrankKinematics& kin, int samples)
    : samples_(samples),
      step_(kFourPi / samples),
      j_(static_cast<std::size_t>(samples)),
      hdj_(static_cast<std::size_t>(samples)),
      tpp_(static_cast<std::size_t>(samples) * kMaxCylinders, 0.0) {
  const double ar = kin.piston_area_m2() * kin.geometry().crank_radius_m();
  for (int n = 0; n < samples; ++n) {
    const double th = n * step_;
    j_[static_cast<std::size_t>(n)] = kin.inertia(th);
    hdj_[static_cast<std::size_t>(n)] = kin.half_dinertia(th);
    for (int c = 0; c < kin.geometry().cylinders; ++c) {
      tpp_[static_cast<std::size_t>(n * kMaxCylinders + c)] = ar * kin.f(th - kin.phase(c + 1));
    }
  }
}

}  // namespace torqued
