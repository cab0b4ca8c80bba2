#include "air_path.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued::sim {

namespace {
constexpr double kRAir = 287.0;    // J/(kg K)
constexpr double kGammaAir = 1.4;  // (-)
constexpr double kPi = std::numbers::pi;

/// Isentropic flow function Ψ(r) of a nozzle at pressure ratio r = p_down/p_up (choked below r_crit).
double psi(double r) noexcept {
  const double g = kGammaAir;
  const double r_crit = std::pow(2.0 / (g + 1.0), g / (g - 1.0));
  r = std::clamp(r, 0.0, 1.0);
  if (r < r_crit) r = r_crit;
  const double v = 2.0 * g / (g - 1.0) * (std::pow(r, 2.0 / g) - std::pow(r, (g + 1.0) / g));
  return std::sqrt(std::max(v, 0.0));
}
}  // namespace

AirPath::AirPath(const AirPathParams& air, const CombustionParams& comb, double displacement_m3,
                 double intake_temp_k)
    : air_(air),
      vol_eff_(comb.vol_efficiency),
      displacement_m3_(displacement_m3),
      temp_k_(intake_temp_k),
      area_max_m2_(kPi * air.throttle_diameter_m * air.throttle_diameter_m / 4.0) {}

double AirPath::area_m2(double u) const noexcept {
  u = std::clamp(u, 0.0, 1.0);
  // Butterfly valve: projected open area ~ 1 − cos(opening angle), opening 0..90° for u 0..1.
  return area_max_m2_ *
         (air_.throttle_leak_frac + (1.0 - air_.throttle_leak_frac) * (1.0 - std::cos(u * kPi / 2)));
}

double AirPath::throttle_flow_kg_s(double u, double p_m_pa) const noexcept {
  const double pa = air_.ambient_pa;
  return area_m2(u) * pa / std::sqrt(kRAir * temp_k_) * psi(p_m_pa / pa);
}

double AirPath::cylinder_flow_kg_s(double p_m_pa, double omega_rad_s) const noexcept {
  return vol_eff_ * p_m_pa * displacement_m3_ * omega_rad_s / (4.0 * kPi * kRAir * temp_k_);
}

double AirPath::throttle_for_map(double p_target_pa, double omega_rad_s) const noexcept {
  const double p = std::min(p_target_pa, 0.97 * air_.ambient_pa);
  const double need = cylinder_flow_kg_s(p, omega_rad_s);
  const double per_area = throttle_flow_kg_s(1.0, p) / area_m2(1.0);
  const double a_rel = need / per_area / area_max_m2_;
  const double c = (a_rel - air_.throttle_leak_frac) / (1.0 - air_.throttle_leak_frac);
  if (c <= 0.0) return 0.0;
  if (c >= 1.0) return 1.0;
  return std::acos(1.0 - c) * 2.0 / kPi;
}

double AirPath::steady_map(double u, double omega_rad_s) const noexcept {
  double lo = 100.0, hi = air_.ambient_pa;
  for (int i = 0; i < 80; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (throttle_flow_kg_s(u, mid) > cylinder_flow_kg_s(mid, omega_rad_s))
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

double AirPath::trapped_air_kg(double p_ivc_pa, int cylinders) const noexcept {
  return vol_eff_ * p_ivc_pa * (displacement_m3_ / cylinders) / (kRAir * temp_k_);
}

void AirPath::step(double u, double omega_rad_s, double dt_s) noexcept {
  mdot_th_ = throttle_flow_kg_s(u, map_pa_);
  const double mdot_cyl = cylinder_flow_kg_s(map_pa_, omega_rad_s);
  map_pa_ += dt_s * kRAir * temp_k_ / air_.manifold_volume_m3 * (mdot_th_ - mdot_cyl);
  map_pa_ = std::clamp(map_pa_, 1000.0, air_.ambient_pa);
}

}  // namespace torqued::sim
