#pragma once
// Crossley & Cook mean-value SI engine (the model behind MathWorks' "Engine Timing Model with Closed Loop
// Control"), as used by Na et al. 2015 (CDC eq. 44-47) and summarised in docs/equations.md §1.6. Units as in
// that model: throttle angle deg, manifold pressure bar, air flows g/s, speed rad/s, torque N m.
//   ṁ_ai = f(θ)·g(p_m),  f = 2.821 − 0.05231θ + 0.10299θ² − 0.00063θ³                         (CDC-45)
//   g(p_m) = 1 for p_m ≤ p_amb/2, else (2/p_amb)·√(p_m·p_amb − p_m²)
//   ṗ_m = 0.41328 (ṁ_ai − ṁ_ao)                                                                (CDC-44)
//   ṁ_ao = −0.366 + 0.08979 N p_m − 0.0337 N p_m² + 0.0001 N² p_m                              (CDC-46)
//   T_e = −181.3 + 379.36 m_a + 21.91 AFR − 0.85 AFR² + 0.26σ − 0.0028σ² + 0.027N − 0.000107N²
//         + 0.00048Nσ + 2.55σ m_a − 0.05σ² m_a,  m_a = ṁ_ao·π/N (g per intake event, 4 cylinders)
//   J Ṅ = T_e − T_l, J = 0.14 kg m²                                                             (CDC-47)
// The induction-to-power delay of the Simulink model is left out (mean-value torque is instantaneous).
#include <array>
#include <cstdint>
#include <random>
#include <vector>

namespace torqued::sim {

struct MeanValueEngineParams {
  double inertia_kgm2 = 0.14;       ///< J (kg m^2)
  double p_amb_bar = 1.0;           ///< ambient pressure (bar)
  double afr = 14.7;                ///< air-fuel ratio (-)
  double spark_advance_deg = 15.0;  ///< σ (deg)
  double throttle_min_deg = 0.0;    ///< throttle range (deg)
  double throttle_max_deg = 60.0;
};

struct MeanValueState {
  double omega_rad_s = 230.0;  ///< N (rad/s)
  double p_m_bar = 0.5;        ///< manifold pressure (bar)
};

class MeanValueEngine {
 public:
  explicit MeanValueEngine(const MeanValueEngineParams& params = {}) : params_(params) {}

  void set_state(const MeanValueState& s) { state_ = s; }
  [[nodiscard]] const MeanValueState& state() const { return state_; }
  [[nodiscard]] const MeanValueEngineParams& params() const { return params_; }

  /// Advances by dt with throttle (deg) and load torque (N m) held, classic RK4 on (N, p_m).
  void step(double dt_s, double throttle_deg, double load_nm);

  [[nodiscard]] double throttle_flow_g_s(double throttle_deg, double p_m_bar) const;  ///< ṁ_ai
  [[nodiscard]] double port_flow_g_s(double omega_rad_s, double p_m_bar) const;       ///< ṁ_ao
  [[nodiscard]] double torque_nm(double omega_rad_s, double p_m_bar) const;           ///< T_e
  /// Throttle angle holding (ω, p_m) in equilibrium with the port flow (steady state), by bisection.
  [[nodiscard]] double steady_throttle_deg(double omega_rad_s, double p_m_bar) const;
  /// Manifold pressure whose torque equals `torque_nm` at ω (steady state), by bisection.
  [[nodiscard]] double steady_pressure_bar(double omega_rad_s, double torque_nm) const;

 private:
  MeanValueEngineParams params_;
  MeanValueState state_{};
};

/// Na 2017 §VI scenario: a PI speed controller on the throttle follows a stepped speed reference while the
/// load is a speed-dependent brake T_l = c0 + c1 N + c2 N² (as CDC §IV.A); speed and load are measured with
/// Gaussian noise (Na: w1, w2). Sampled every step_s; the plant integrates with `substeps` RK4 steps per
/// sample.
struct NaScenarioConfig {
  double duration_s = 30.0;
  double step_s = 0.001;
  int substeps = 4;
  std::vector<std::array<double, 2>> speed_steps_rpm{
      {0.0, 2200.0}, {4.0, 2500.0}, {12.0, 2200.0}, {20.0, 1900.0}, {26.0, 2200.0}};  ///< {t_s, rpm}
  std::array<double, 3> load_coeffs{5.0, 0.05, 5e-4};  ///< c0 (N m), c1 (N m s/rad), c2 (N m s^2/rad^2)
  double kp_deg_per_rad_s = 0.08;                      ///< PI speed controller on throttle
  double ki_deg_per_rad = 0.6;
  double speed_noise_rpm = 0.0;  ///< 1σ of w1 on the measured speed (rpm)
  double load_noise_nm = 0.0;    ///< 1σ of w2 on the measured load torque (N m)
  double maf_noise_g_s = 0.0;    ///< 1σ on the measured air mass flow (g/s)
  std::uint64_t seed = 1;
  MeanValueEngineParams engine{};
};

/// One sample of the scenario: measured (noisy) inputs of the estimators and the truth.
struct NaScenarioSample {
  double t_s;
  double speed_rad_s;  ///< measured ω
  double load_nm;      ///< measured τ_l
  double maf_kg_s;     ///< measured ṁ_ai
  double true_speed_rad_s;
  double true_load_nm;
  double true_torque_nm;  ///< effective torque τ_e (truth)
  double throttle_deg;
  double p_m_bar;
};

/// Runs the scenario (deterministic for a given seed). Not real-time: allocates the result.
[[nodiscard]] std::vector<NaScenarioSample> run_na_scenario(const NaScenarioConfig& cfg);

}  // namespace torqued::sim
