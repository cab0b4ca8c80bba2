#include "engine_model.hpp"

#include <cmath>
#include <numbers>

#include "crank_kinematics.hpp"

namespace torqued::sim {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr double kFourPi = 4.0 * kPi;
}  // namespace

EngineModel::EngineModel(const Scenario& sc)
    : n_(sc.engine.cylinders),
      geo_(sc.engine),
      comb_(sc.combustion),
      fric_(sc.friction),
      r_(sc.engine.crank_radius_m()),
      l_(sc.engine.rod_m),
      lambda_(r_ / l_),
      area_(kPi * sc.engine.bore_m * sc.engine.bore_m / 4.0),
      vc_(area_ * 2.0 * r_ / (sc.engine.compression_ratio - 1.0)),
      evo_rad_(sc.combustion.evo_deg * kDeg),
      bd_end_rad_(sc.combustion.blowdown_end_deg * kDeg),
      dur_rad_(sc.combustion.burn_duration_deg * kDeg) {
  const CrankKinematics kin(sc.engine);
  for (int c = 0; c < n_; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    tdc_base_[cu] = sc.engine.tdc_offset_rad + kin.phase(c + 1);
    sin_base_[cu] = std::sin(tdc_base_[cu]);
    cos_base_[cu] = std::cos(tdc_base_[cu]);
  }
}

double EngineModel::volume_m3(double psi) const noexcept {
  const double s = std::sin(psi);
  return vc_ + area_ * (r_ * (1.0 - std::cos(psi)) + l_ * (1.0 - std::sqrt(1.0 - lambda_ * lambda_ * s * s)));
}

double EngineModel::friction_nm(double omega_rad_s, double oil_temp_c) const noexcept {
  // Energies 2019 eq. (27): T_fric = (C1 + C2 n + C3 n²) e^{C4 t_oil}, n in rpm, t_oil in °C, with the
  // paper's Table values C1 = −23.86, C2 = 2.45e−3, C3 = −5.20e−6, C4 = −4.67e−3. As printed the bracket is
  // negative (−26 N m at 2000 rpm, 90 °C): the paper counts friction as a torque acting on the crank. We use
  // the loss T_fric = −(C1 + C2 n + C3 n²) e^{C4 t_oil} > 0 (docs/simulator.md §4).
  constexpr double kC1 = -23.86, kC2 = 2.45e-3, kC3 = -5.20e-6, kC4 = -4.67e-3;
  const double n = omega_rad_s * 30.0 / kPi;
  if (!fric_.paper_law) {
    // Bed engines: FMEP polynomial in speed; mean torque = FMEP V_d / 4π (4-stroke).
    const double k = n / 1000.0;
    const double fmep_pa = 1e3 * (fric_.fmep0_kpa + fric_.fmep1_kpa * k + fric_.fmep2_kpa * k * k) *
                           std::exp(fric_.oil_coeff_per_c * (oil_temp_c - fric_.oil_ref_c));
    return fmep_pa * displacement_m3() / kFourPi;
  }
  return -(kC1 + kC2 * n + kC3 * n * n) * std::exp(kC4 * oil_temp_c);
}

double EngineModel::wiebe_dq(const CylinderEvent& e, double psi) const noexcept {
  // Wiebe: x_b = 1 − exp(−a ((ψ − ψ_0)/Δψ)^{m+1}); dQ/dψ = Q dx_b/dψ (Heywood eq. 9.23).
  if (e.q_total_j <= 0.0) return 0.0;
  const double x = (psi - e.soc_rad) / dur_rad_;
  if (x <= 0.0) return 0.0;
  const double a = comb_.wiebe_a, m = comb_.wiebe_m;
  const double xm = m == 2.0 ? x * x : std::pow(x, m);
  return e.q_total_j * a * (m + 1.0) / dur_rad_ * xm * std::exp(-a * xm * x);
}

void EngineModel::derivative(double theta_w, const State& y, const HeldInputs& in, State& dy,
                             ModelEval* ev) const noexcept {
  double sum_ff = 0.0, sum_fg = 0.0, t_ind = 0.0;
  const double gamma = comb_.gamma;
  const double p_cc = geo_.crankcase_pressure_pa;
  for (std::size_t k = 2; k < static_cast<std::size_t>(kStateSize); ++k) dy[k] = 0.0;
  // One sincos per evaluation: sin/cos(θ − b_c) by the angle-difference identities.
  const double st = std::sin(theta_w), ct = std::cos(theta_w);
  for (int c = 0; c < n_; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    const double psi0 = theta_w - tdc_base_[cu];
    const double s = st * cos_base_[cu] - ct * sin_base_[cu];
    const double co = ct * cos_base_[cu] + st * sin_base_[cu];
    const double q = 1.0 - lambda_ * lambda_ * s * s;
    const double root = std::sqrt(q);
    const double s2 = 2.0 * s * co;
    const double c2 = co * co - s * s;
    // f, g: docs/equations.md §0 (EN-5 corrected), same formulas as CrankKinematics.
    const double f = s + lambda_ * s2 / (2.0 * root);
    const double g = co + lambda_ * c2 / root + lambda_ * lambda_ * lambda_ * s2 * s2 / (4.0 * q * root);
    sum_ff += f * f;
    sum_fg += f * g;

    double p = in.map_pa;
    const CylinderEvent& e = events_[cu];
    const double psi_e = theta_w - e.theta_tdc_rad;
    if (e.active && psi_e <= bd_end_rad_) {
      const double p_ode = y[2 + cu];
      const double vol = vc_ + area_ * (r_ * (1.0 - co) + l_ * (1.0 - root));
      const double dvol = area_ * r_ * f;
      dy[2 + cu] = (gamma - 1.0) / vol * wiebe_dq(e, psi_e) - gamma * p_ode / vol * dvol;
      if (psi_e > evo_rad_) {
        // Exhaust blowdown: blend from the polytrope to the exhaust pressure between EVO and blowdown end.
        const double w = 0.5 * (1.0 + std::cos(kPi * (psi_e - evo_rad_) / (bd_end_rad_ - evo_rad_)));
        p = comb_.exhaust_pa + (p_ode - comb_.exhaust_pa) * w;
      } else {
        p = p_ode;
      }
    } else {
      double a = std::fmod(psi0, kFourPi);
      if (a < 0.0) a += kFourPi;
      // Exhaust stroke at back-pressure, intake stroke (and any gap before the next IVC) at MAP.
      p = (a >= bd_end_rad_ && a < 2.0 * kPi) ? comb_.exhaust_pa : in.map_pa;
    }
    const double tq = (p - p_cc) * area_ * r_ * f;  // EN-9
    t_ind += tq;
    if (ev != nullptr) {
      ev->t_cyl_nm[cu] = tq;
      ev->p_pa[cu] = p;
    }
  }
  const double mr2 = geo_.m_osc_kg * r_ * r_;
  const double inertia = geo_.j_rot_kgm2 + mr2 * sum_ff;  // CK-1
  const double half_dj = mr2 * sum_fg;
  double omega;
  if (in.locked_omega_rad_s > 0.0) {
    omega = in.locked_omega_rad_s;
    dy[1] = half_dj * omega * omega;  // d(½ J ω²)/dθ at constant ω
  } else {
    omega = std::sqrt(std::max(2.0 * y[1] / inertia, 1e-6));
  }
  const double t_fric = friction_nm(omega, in.oil_temp_c);
  if (in.locked_omega_rad_s <= 0.0) dy[1] = t_ind - t_fric - in.t_load_nm;  // CF-2 energy form
  dy[0] = 1.0 / omega;
  if (ev != nullptr) {
    ev->omega_rad_s = omega;
    ev->t_ind_nm = t_ind;
    ev->t_fric_nm = t_fric;
    ev->inertia_kgm2 = inertia;
    ev->half_dinertia = half_dj;
  }
}

}  // namespace torqued::sim
