#include "mean_value_engine.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued::sim {

double MeanValueEngine::throttle_flow_g_s(double th, double p_m) const {
  const double f = 2.821 - 0.05231 * th + 0.10299 * th * th - 0.00063 * th * th * th;  // CDC-45
  const double pa = params_.p_amb_bar;
  double g = 1.0;
  if (p_m > 0.5 * pa) {
    const double r = std::max(0.0, p_m * pa - p_m * p_m);
    g = (2.0 / pa) * std::sqrt(r);
  }
  return f * g;
}

double MeanValueEngine::port_flow_g_s(double n, double p_m) const {
  return -0.366 + 0.08979 * n * p_m - 0.0337 * n * p_m * p_m + 0.0001 * n * n * p_m;  // CDC-46
}

double MeanValueEngine::torque_nm(double n, double p_m) const {
  const double m_a =
      std::max(0.0, port_flow_g_s(n, p_m)) * std::numbers::pi / std::max(n, 1.0);  // g per event
  const double afr = params_.afr;
  const double sg = params_.spark_advance_deg;
  return -181.3 + 379.36 * m_a + 21.91 * afr - 0.85 * afr * afr + 0.26 * sg - 0.0028 * sg * sg + 0.027 * n -
         0.000107 * n * n + 0.00048 * n * sg + 2.55 * sg * m_a - 0.05 * sg * sg * m_a;  // CDC-47 torque map
}

void MeanValueEngine::step(double dt, double th, double load) {
  auto deriv = [&](double n, double p) {
    const double dn = (torque_nm(n, p) - load) / params_.inertia_kgm2;
    const double dp = 0.41328 * (throttle_flow_g_s(th, p) - port_flow_g_s(n, p));
    return std::array<double, 2>{dn, dp};
  };
  const double n0 = state_.omega_rad_s, p0 = state_.p_m_bar;
  const auto k1 = deriv(n0, p0);
  const auto k2 = deriv(n0 + 0.5 * dt * k1[0], p0 + 0.5 * dt * k1[1]);
  const auto k3 = deriv(n0 + 0.5 * dt * k2[0], p0 + 0.5 * dt * k2[1]);
  const auto k4 = deriv(n0 + dt * k3[0], p0 + dt * k3[1]);
  state_.omega_rad_s = n0 + dt / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
  state_.p_m_bar =
      std::clamp(p0 + dt / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]), 0.01, params_.p_amb_bar);
}

double MeanValueEngine::steady_throttle_deg(double n, double p_m) const {
  const double target = port_flow_g_s(n, p_m);
  double lo = params_.throttle_min_deg, hi = params_.throttle_max_deg;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (throttle_flow_g_s(mid, p_m) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double MeanValueEngine::steady_pressure_bar(double n, double torque) const {
  double lo = 0.05, hi = params_.p_amb_bar * 0.99;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (torque_nm(n, mid) < torque ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::vector<NaScenarioSample> run_na_scenario(const NaScenarioConfig& cfg) {
  MeanValueEngine engine(cfg.engine);
  constexpr double kRpmToRadS = std::numbers::pi / 30.0;
  auto load_of = [&](double n) {
    return cfg.load_coeffs[0] + cfg.load_coeffs[1] * n + cfg.load_coeffs[2] * n * n;
  };
  auto reference = [&](double t) {
    double rpm = cfg.speed_steps_rpm.empty() ? 2000.0 : cfg.speed_steps_rpm.front()[1];
    for (const auto& s : cfg.speed_steps_rpm) {
      if (t >= s[0]) rpm = s[1];
    }
    return rpm * kRpmToRadS;
  };
  // Start in equilibrium at the first reference speed.
  const double n0 = reference(0.0);
  const double p0 = engine.steady_pressure_bar(n0, load_of(n0));
  engine.set_state({n0, p0});
  const double th0 = engine.steady_throttle_deg(n0, p0);
  double integ = th0 / cfg.ki_deg_per_rad;  // PI integrator holds the steady throttle

  std::mt19937_64 rng(cfg.seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const auto steps = static_cast<std::size_t>(std::llround(cfg.duration_s / cfg.step_s));
  std::vector<NaScenarioSample> out;
  out.reserve(steps);
  const double h = cfg.step_s / cfg.substeps;
  for (std::size_t i = 0; i < steps; ++i) {
    const double t = static_cast<double>(i) * cfg.step_s;
    const auto& st = engine.state();
    const double n = st.omega_rad_s;
    const double load = load_of(n);
    // PI speed controller on the throttle with clamping anti-wind-up (Na §VI: "speed feedback controller").
    const double err = reference(t) - n;
    double th = cfg.kp_deg_per_rad_s * err + cfg.ki_deg_per_rad * integ;
    const double th_sat = std::clamp(th, cfg.engine.throttle_min_deg, cfg.engine.throttle_max_deg);
    if (th == th_sat) integ += err * cfg.step_s;
    th = th_sat;
    NaScenarioSample s{};
    s.t_s = t;
    s.true_speed_rad_s = n;
    s.true_load_nm = load;
    s.true_torque_nm = engine.torque_nm(n, st.p_m_bar);
    s.throttle_deg = th;
    s.p_m_bar = st.p_m_bar;
    const double maf_g_s = engine.throttle_flow_g_s(th, st.p_m_bar);
    s.speed_rad_s = n + cfg.speed_noise_rpm * kRpmToRadS * unit(rng);
    s.load_nm = load + cfg.load_noise_nm * unit(rng);
    s.maf_kg_s = 1e-3 * (maf_g_s + cfg.maf_noise_g_s * unit(rng));
    out.push_back(s);
    for (int k = 0; k < cfg.substeps; ++k) engine.step(h, th, load_of(engine.state().omega_rad_s));
  }
  return out;
}

}  // namespace torqued::sim
