// Estimator keys of the configuration table (estimators/core/params.hpp). One line per key: when a field is
// added to params.hpp, add it here with its bounds, unit and description (the example-YAML test then demands
// its docs).
#include "schema_builders.hpp"

namespace torqued::schema_detail {
namespace {

Bounds open_closed(double lo, double hi) { return {lo, hi, true, false}; }
Bounds closed_open(double lo, double hi) { return {lo, hi, false, true}; }
Bounds open_open(double lo, double hi) { return {lo, hi, true, true}; }

}  // namespace

#define TQ_NUM(key, field, bounds, unit, desc) \
  t.push_back(number("estimators." key, TQ_REF(double, estimators.field), bounds, unit, desc))
#define TQ_INT(key, field, bounds, unit, desc) \
  t.push_back(integer<int>("estimators." key, TQ_REF(int, estimators.field), bounds, unit, desc))
#define TQ_BOOL(key, field, desc) \
  t.push_back(boolean("estimators." key, TQ_REF(bool, estimators.field), desc))
#define TQ_ARR2(key, field, bounds, unit, desc) \
  t.push_back(fixed_list<2>("estimators." key, TQ_REF(Arr2, estimators.field), bounds, unit, desc))

namespace {
using Arr2 = std::array<double, 2>;
using Arr4 = std::array<double, 4>;

/// The time-triggered estimators of Na et al. (docs/equations.md §1).
void add_time_estimators(std::vector<SchemaEntry>& t) {
  // Time-triggered pipeline (docs/equations.md §1).
  TQ_NUM("time_pipeline.step_s", time_pipeline.step_s, closed(1e-5, 0.1), "s",
         "time pipeline step T_s (1 ms = 1 kHz)");
  TQ_BOOL("time_pipeline.cycle_averaged_speed", time_pipeline.cycle_averaged_speed,
          "mean speed over 720 deg (true) or over the last combustion segment (false)");
  TQ_NUM("time_pipeline.inertia_kgm2", time_pipeline.inertia_kgm2, closed(0.0, 100.0), "kg m^2",
         "J of Na-8; 0 = engine.j_rot_kgm2 + cycle-mean oscillating inertia");
  TQ_NUM("time_pipeline.speed_timeout_s", time_pipeline.speed_timeout_s, open_closed(0.0, 10.0), "s",
         "mean speed is stale when the newest tooth is older than this");
  // Enabled flags of the Na estimators live in TimePipelineParams; mirrored into the toggles.
  auto na_toggle = [&t](const char* name, bool TimePipelineParams::*flag, Ref<bool> toggle,
                        const char* desc) {
    SchemaEntry e = boolean(std::string("estimators.") + name + ".enabled", toggle, desc);
    e.set = [flag, toggle](Config& c, const ConfigValue& v) {
      toggle(c) = v.b;
      c.estimators.time_pipeline.*flag = v.b;
    };
    t.push_back(std::move(e));
  };
  na_toggle("uio", &TimePipelineParams::uio, TQ_REF(bool, estimators.uio.enabled),
            "run the unknown-input observer (Na-14)");
  TQ_NUM("uio.k_s", uio.params.k_s, open_closed(0.0, 10.0), "s", "filter constant k (Na-9)");
  na_toggle("sliding_mode", &TimePipelineParams::sliding_mode, TQ_REF(bool, estimators.sliding_mode.enabled),
            "run the sliding-mode estimator (Na-19..21)");
  TQ_NUM("sliding_mode.k_s", sliding_mode.params.k_s, open_closed(0.0, 10.0), "s",
         "output low-pass constant (Na-21)");
  TQ_NUM("sliding_mode.lambda1_nm", sliding_mode.params.lambda1_nm, open_closed(0.0, 1e5), "N m",
         "switching gain, > sup|torque| (Na-19)");
  na_toggle("dirty_diff", &TimePipelineParams::dirty_diff, TQ_REF(bool, estimators.dirty_diff.enabled),
            "run the dirty-differentiation estimator (Na-24)");
  TQ_NUM("dirty_diff.k_s", dirty_diff.params.k_s, open_closed(0.0, 10.0), "s",
         "differentiation filter constant (Na-24)");
  na_toggle("adaptive", &TimePipelineParams::adaptive, TQ_REF(bool, estimators.adaptive.enabled),
            "run the adaptive parameter estimator (Na-41..54)");
  TQ_NUM("adaptive.k_s", adaptive.params.k_s, open_closed(0.0, 10.0), "s", "filter constant k");
  TQ_NUM("adaptive.ell", adaptive.params.ell, open_closed(0.0, 1e4), "1/s", "forgetting factor l (Na-45)");
  TQ_ARR2("adaptive.gamma", adaptive.params.gamma, open_closed(0.0, 1e9), "", "gain diagonal of law (Na-50)");
  TQ_NUM("adaptive.kappa", adaptive.params.kappa, closed(0.0, 1e3), "", "weight of W2 (Na-50/54)");
  TQ_BOOL("adaptive.time_varying_gain", adaptive.params.time_varying_gain,
          "use law (Na-52/54) instead of (Na-50)");
  TQ_ARR2("adaptive.k0", adaptive.params.k0, open_closed(0.0, 1e9), "", "K0 diagonal, K(0) = K0^-1 (Na-52)");
  TQ_NUM("adaptive.sigma", adaptive.params.sigma, closed(0.0, 1e9), "",
         "excitation threshold on lambda_min(P) (Na Remark 9)");
  TQ_ARR2("adaptive.phi_scale", adaptive.params.phi_scale, open_closed(0.0, 1e9), "[s/rad, s/kg]",
          "regressor normalisation [speed, air mass flow]");
  TQ_ARR2("adaptive.gamma_tv", adaptive.params.gamma_tv, open_closed(0.0, 1e9), "1/s",
          "gain diagonal of law (Na-54)");
  TQ_NUM("adaptive.k0_floor", adaptive.params.k0_floor, closed(0.0, 1.0), "",
         "K^-1 never decays below k0_floor K0");
  TQ_ARR2("adaptive.theta0", adaptive.params.theta0, closed(-1e9, 1e9), "N m",
          "initial parameters (normalised units)");
}

/// The angle-triggered observers: preprocessor, Kalman, Fourier (docs/equations.md §2).
void add_angle_observers(std::vector<SchemaEntry>& t) {
  // Angle-triggered (docs/equations.md §2).
  TQ_NUM("preprocess.lowpass_hz", preprocess.lowpass_hz, open_closed(0.0, 1e5), "Hz",
         "low-pass cut-off on tooth speed (EN §2.1)");
  TQ_NUM("preprocess.accel_jerk_sd", preprocess.accel_jerk_sd, open_closed(0.0, 1e12), "rad/s^3/sqrt(s)",
         "white-jerk intensity of the speed/acceleration Kalman filter");
  TQ_NUM("preprocess.edge_noise_deg", preprocess.edge_noise_deg, open_closed(0.0, 10.0), "deg",
         "residual edge-angle error, 1 sigma");
  TQ_NUM("preprocess.jitter_s", preprocess.jitter_s, closed(0.0, 1e-2), "s",
         "edge timestamp jitter, 1 sigma");
  TQ_BOOL("kalman.enabled", kalman.enabled, "run the time-varying Kalman filter (CK)");
  TQ_NUM("kalman.delta", kalman.params.delta, closed(1e-3, 1e3), "1/rad",
         "coloured-noise pole of h(z) (CK-18); at least 0.001: below it the pole rounds to 1 (a random walk, "
         "whose "
         "stationary Q does not exist)");
  TQ_NUM("kalman.torque_sd_nm", kalman.params.torque_sd_nm, open_closed(0.0, 1e5), "N m",
         "stationary 1 sigma of the net torque; sets Q without the gas torque model");
  TQ_NUM("kalman.model_torque_sd_nm", kalman.params.model_torque_sd_nm, open_closed(0.0, 1e5), "N m",
         "stationary 1 sigma of what the gas torque model misses; sets Q while the model is valid");
  TQ_NUM("kalman.model_delta", kalman.params.model_delta, closed(1e-3, 1e3), "1/rad",
         "coloured-noise pole of h(z) (CK-18) while the gas torque model is valid; at least 0.001, as "
         "kalman.delta");
  TQ_NUM("kalman.edge_noise_deg", kalman.params.edge_noise_deg, open_closed(0.0, 10.0), "deg",
         "edge-angle error used for R");
  TQ_NUM("kalman.jitter_s", kalman.params.jitter_s, closed(0.0, 1e-2), "s", "timestamp jitter used for R");
  TQ_INT("kalman.smoother_lag", kalman.params.smoother_lag, closed(0, 12), "teeth",
         "fixed-lag smoother output (0 = paper's predictor)");
  TQ_BOOL("kalman.periodic_gains", kalman.params.periodic_gains,
          "precomputed periodic gains (APS) instead of exact Riccati");
  TQ_BOOL("kalman.differenced_edge_noise", kalman.params.differenced_edge_noise,
          "model edge-angle error and jitter as the difference of a period's two edges (MA(1)), not white R");
  TQ_BOOL(
      "kalman.gas_model", kalman.params.gas_model,
      "feed the cylinder-pressure model's gas torque ripple (MAP, measured cylinder works) as a known input");
  TQ_NUM("kalman.min_rpm", kalman.params.min_rpm, open_closed(0.0, 20000.0), "rpm",
         "lowest speed of the APS gain schedule");
  TQ_NUM("kalman.max_rpm", kalman.params.max_rpm, open_closed(0.0, 20000.0), "rpm",
         "highest speed of the APS gain schedule");
  TQ_INT("kalman.speed_bins", kalman.params.speed_bins, closed(1, 256), "",
         "APS gain sets, log-spaced in speed");
  // The gas model's burn-phasing learner (estimators/learners/burn_phase_learner.hpp).
  TQ_BOOL(
      "kalman.burn_phase_learn", kalman.params.burn_phase.learn,
      "learn an offset of the gas model's burn centroid from the firing-order phase of the estimate against "
      "the model (with kalman.gas_model and energies.incycle_spark_phasing)");
  TQ_NUM("kalman.burn_phase_gain", kalman.params.burn_phase.gain, open_closed(0.0, 10.0), "deg/deg",
         "integrator gain: offset step = -gain x the cycle's model-behind-estimate firing-order lag");
  TQ_NUM("kalman.burn_phase_max_step_deg", kalman.params.burn_phase.max_step_deg, open_closed(0.0, 5.0),
         "deg", "largest offset step per used cycle");
  TQ_NUM("kalman.burn_phase_min_offset_deg", kalman.params.burn_phase.min_offset_deg, closed(-16.0, 0.0),
         "deg",
         "lower bound of the learned offset (the ripple tables reach 16 deg before "
         "energies.burn_centroid_atdc_deg)");
  TQ_NUM("kalman.burn_phase_max_offset_deg", kalman.params.burn_phase.max_offset_deg, closed(0.0, 28.0),
         "deg",
         "upper bound of the learned offset (the ripple tables reach 28 deg after "
         "energies.burn_centroid_atdc_deg)");
  TQ_NUM("kalman.burn_phase_min_ripple_nm", kalman.params.burn_phase.min_ripple_nm, closed(0.0, 1e5), "N m",
         "firing-order amplitude of the model's ripple below which a cycle does not move the offset");
  TQ_INT("kalman.burn_phase_quality_cycles", kalman.params.burn_phase.quality_cycles, closed(1, 10000),
         "cycles", "time constant of the mean phase difference that decides converged");
  TQ_NUM("kalman.burn_phase_converged_deg", kalman.params.burn_phase.converged_deg, open_closed(0.0, 10.0),
         "deg", "mean |model-behind-estimate lag| at or below which the offset reads converged");
  TQ_INT("kalman.burn_phase_min_cycles", kalman.params.burn_phase.min_cycles, closed(0, 100000), "cycles",
         "used cycles before the offset may read converged");
  TQ_BOOL("fourier.enabled", fourier.enabled, "run the adaptive Fourier observer (CF)");
  TQ_INT("fourier.harmonics", fourier.params.harmonics, closed(1, 64), "",
         "n_h harmonics of the 720 deg cycle (CF §V.B)");
  TQ_NUM("fourier.l_ke", fourier.params.l_ke, open_closed(0.0, 1e6), "1/rad", "L_ke, must satisfy CF-14");
  TQ_NUM("fourier.l_a0", fourier.params.l_a0, closed(0.0, 1e6), "1/rad^2", "L_a0");
  TQ_NUM("fourier.l_ref", fourier.params.l_ref, closed(0.0, 1e6), "1/rad^2", "L_ref: l_ai = l_bi = i L_ref");
  TQ_NUM("fourier.model_l_ref", fourier.params.model_l_ref, closed(0.0, 1e6), "1/rad^2",
         "L_ref while the gas torque model is valid");
  TQ_NUM("fourier.gain_ref_rpm", fourier.params.gain_ref_rpm, closed(0.0, 20000.0), "rpm",
         ">0: coefficient gains x min(1, (gain_ref_rpm/rpm)^2); 0 = fixed gains as in the paper");
  TQ_BOOL(
      "fourier.gas_model", fourier.params.gas_model,
      "feed the cylinder-pressure model's gas torque ripple (MAP, measured cylinder works) as a known input");
  TQ_INT("fourier.output_lag", fourier.params.output_lag, closed(0, 6), "teeth",
         "report the torque at tooth k-lag from the coefficients after tooth k");
}

/// The Energies 2019 chain: windows, load RLS, ESO (docs/equations.md §3-4).
void add_energies(std::vector<SchemaEntry>& t) {
  // Energies 2019 chain and beyond (docs/equations.md §3-4).
  TQ_BOOL("energies.enabled", energies.enabled, "run the load RLS + ESO chain (EN)");
  TQ_NUM("energies.window_start_btdc_deg", energies.params.window_start_btdc_deg, open_closed(0.0, 180.0),
         "deg", "RLS window start before TDC (EN-10)");
  TQ_NUM("energies.window_end_btdc_deg", energies.params.window_end_btdc_deg, closed_open(0.0, 180.0), "deg",
         "RLS window end before TDC, < start");
  TQ_NUM("energies.polytropic_kappa", energies.params.polytropic_kappa, open_closed(1.0, 2.0), "",
         "polytropic exponent");
  TQ_NUM("energies.rls_forgetting", energies.params.rls_forgetting, closed(0.5, 1.0), "",
         "RLS forgetting factor");
  TQ_NUM("energies.lowpass_hz", energies.params.lowpass_hz, open_closed(0.0, 1e5), "Hz",
         "speed pre-filter cut-off");
  TQ_NUM("energies.eso_omega0", energies.params.eso_omega0, open_closed(0.0, 1e5), "rad/s",
         "ESO bandwidth (EN-23)");
  TQ_NUM("energies.fuel_lhv_j_kg", energies.params.fuel_lhv_j_kg, open_closed(0.0, 1e9), "J/kg",
         "fuel lower heating value");
  TQ_NUM("energies.eso_base_efficiency", energies.params.eso_base_efficiency, open_closed(0.0, 1.0), "",
         "ignition x in-cycle efficiency at the nominal point");
  TQ_NUM("energies.ivc_abdc_deg", energies.params.ivc_abdc_deg, closed(0.0, 180.0), "deg",
         "intake valve closing after BDC");
  TQ_NUM("energies.evo_atdc_deg", energies.params.evo_atdc_deg, closed(0.0, 360.0), "deg",
         "exhaust valve opening after firing TDC");
  TQ_NUM("energies.blowdown_end_atdc_deg", energies.params.blowdown_end_atdc_deg, closed(0.0, 720.0), "deg",
         "cylinder pressure reaches the exhaust pressure here (after firing TDC)");
  TQ_NUM("energies.exhaust_pressure_pa", energies.params.exhaust_pressure_pa, open_closed(0.0, 1e7), "Pa",
         "exhaust back-pressure");
  TQ_NUM("energies.ivc_pressure_factor", energies.params.ivc_pressure_factor, open_closed(0.0, 5.0), "",
         "p_IVC = factor x MAP");
  TQ_BOOL("energies.model_expansion_cylinder", energies.params.model_expansion_cylinder,
          "model the cylinder that fired 180 deg earlier in the RLS window");
  TQ_BOOL("energies.rls_estimate_inertia", energies.params.rls_estimate_inertia,
          "regress [accel, 1] (paper) instead of [1] with known J");
  TQ_INT("energies.rls_min_windows", energies.params.rls_min_windows, closed(1, 100000), "",
         "windows before the RLS load counts as converged");
  TQ_NUM("energies.energy_window_deg", energies.params.energy_window_deg, open_closed(0.0, 180.0), "deg",
         "kinetic-energy averaging window");
  TQ_NUM("energies.cycle_ke_window_deg", energies.params.cycle_ke_window_deg, closed(0.0, 300.0), "deg",
         "720° balance (brake/indicated): kinetic energy averaged over this window ending energy_window/2 "
         "after boundary 0 (0: per-cylinder window)");
  TQ_NUM("energies.cylinder_window_deg", energies.params.cylinder_window_deg, closed(0.0, 180.0), "deg",
         "per-cylinder segment work only (shares, imbalance, misfire): kinetic energy averaged over this "
         "window ending energy_window/2 after each boundary; jitter noise ~ 1/window; below 720/cylinders "
         "(0: energy_window)");
  TQ_NUM("energies.cylinder_window_taper", energies.params.cylinder_window_taper, closed(0.0, 1.0), "",
         "per-cylinder window's taper: tooth weights 1 - taper*(2x-1)^2, x the position in the window (0: "
         "rectangle, 1: parabola: less jitter noise at high speed)");
  TQ_NUM("energies.segment_offset_deg", energies.params.segment_offset_deg, closed(-180.0, 180.0), "deg",
         "segment boundary relative to firing TDC");
  TQ_NUM("energies.idle_max_rpm", energies.params.idle_max_rpm, open_closed(0.0, 20000.0), "rpm",
         "idle (friction C4 learning) below this speed");
  TQ_NUM("energies.idle_max_load_nm", energies.params.idle_max_load_nm, closed(0.0, 1e4), "N m",
         "and |load| below this");
  TQ_NUM("energies.rls_change_threshold", energies.params.rls_change_threshold, closed(0.0, 1000.0), "",
         "crank-only load change: CUSUM of the per-firing load innovations (sigma units) above this re-seeds "
         "the RLS at the cycle mean (0: RLS alone)");
  TQ_NUM("energies.rls_step_min_sd_nm", energies.params.rls_step_min_sd_nm, open_closed(0.0, 1e3), "N m",
         "floor of the sigma of the load innovations");
  TQ_NUM("energies.rls_change_max_sd_nm", energies.params.rls_change_max_sd_nm, open_closed(0.0, 1e3), "N m",
         "no crank-only load-change tracking while the cycle-mean load's steady sigma exceeds this");
  TQ_NUM("energies.can_load_latency_s", energies.params.can_load_latency_s, closed(0.0, 0.1), "s",
         "CAN load torque lag behind the flange (sensor lag + half the frame period); the energy balance is "
         "aligned to it");
  TQ_INT("energies.rls_window_shifts", energies.params.rls_window_shifts, closed(1, 64), "",
         "each RLS window also shifted 1..n-1 teeth earlier");
}

/// The in-cycle gas torque model and the rest of the energies section.
void add_gas_model(std::vector<SchemaEntry>& t) {
  TQ_NUM("energies.burn_duration_deg", energies.params.burn_duration_deg, closed(0.0, 120.0), "deg",
         "in-cycle gas torque model (Kalman known input): heat release spread over this angle around the "
         "burn centroid; 0 = lumped");
  TQ_NUM("energies.burn_wiebe_a", energies.params.burn_wiebe_a, closed(0.0, 20.0), "",
         "in-cycle gas torque model: burn shape a Wiebe function with this efficiency parameter a (Heywood "
         "9.2.1: 5); 0 = raised cosine");
  TQ_NUM("energies.burn_wiebe_m", energies.params.burn_wiebe_m, closed(0.0, 10.0), "",
         "in-cycle gas torque model: the Wiebe function's form factor m (Heywood 9.2.1: 2)");
  TQ_NUM("energies.incycle_compression_kappa", energies.params.incycle_compression_kappa, closed(0.0, 2.0),
         "", "in-cycle gas torque model: polytropic exponent of compression; 0 = energies.polytropic_kappa");
  TQ_NUM("energies.incycle_expansion_kappa", energies.params.incycle_expansion_kappa, closed(0.0, 2.0), "",
         "in-cycle gas torque model: polytropic exponent of the burned gas's expansion (burned-gas gamma "
         "1.2-1.3, Heywood ch. 4); 0 = energies.polytropic_kappa");
  TQ_BOOL("energies.incycle_spark_phasing", energies.params.incycle_spark_phasing,
          "in-cycle gas torque model's combustion phasing: its burn centroid follows the spark advance, "
          "energies.burn_delay_deg - advance (as the RLS closure), clamped to 0-60 deg and tabulated in "
          "2 deg steps from 16 deg before to 28 deg after energies.burn_centroid_atdc_deg (beyond: the end "
          "table); until a spark advance arrives, or false: fixed at energies.burn_centroid_atdc_deg. When "
          "CAN is lost the last advance "
          "seen is held, as for the RLS closure (docs/angle_estimators.md). Only the tables a clamped "
          "centroid can reach are built at start, and with can.signals.spark_advance unmapped only the "
          "fixed centroid's");
  TQ_NUM("energies.burn_centroid_atdc_deg", energies.params.burn_centroid_atdc_deg, closed(-90.0, 180.0),
         "deg", "heat release lumped here until a spark advance arrives (or without spark phasing)");
  TQ_NUM("energies.burn_delay_deg", energies.params.burn_delay_deg, closed(0.0, 180.0), "deg",
         "spark to equivalent burn centroid: centroid = delay - advance");
  TQ_BOOL("energies.inertia.learn", energies.params.inertia.learn,
          "learn J = k x engine.j_rot_kgm2 from consecutive cycles while a load signal is present "
          "(estimators/learners/inertia_learner.hpp)");
  TQ_NUM("energies.inertia.prior_rel_sd", energies.params.inertia.prior_rel_sd, open_closed(0.0, 1.0), "",
         "1 sigma of the spec-sheet inertia, fraction (catalogue vs fitted flywheel, clutch, damper)");
  TQ_NUM(
      "energies.inertia.min_step_nm", energies.params.inertia.min_step_nm, open_closed(0.0, 1e4), "N m",
      "a pair of consecutive cycles counts only when J_spec x accel changes by more than this between them");
  TQ_NUM("energies.inertia.obs_sd_nm", energies.params.inertia.obs_sd_nm, open_closed(0.0, 1e4), "N m",
         "1 sigma of one pair's torque residual (CAN load lag, fuelling steps)");
  TQ_NUM("energies.inertia.gate_sigma", energies.params.inertia.gate_sigma, open_closed(0.0, 1e3), "",
         "pairs farther than this many sigma from the current fit are rejected");
  TQ_NUM("energies.inertia.max_fuel_change", energies.params.inertia.max_fuel_change, closed(0.0, 1.0), "",
         "firing pairs: fuel per injection within this fraction of each other");
  TQ_NUM("energies.inertia.max_map_change_pa", energies.params.inertia.max_map_change_pa, closed(0.0, 1e6),
         "Pa", "firing pairs: MAP within this of each other");
  TQ_NUM("energies.inertia.apply_max_sd", energies.params.inertia.apply_max_sd, open_closed(0.0, 1.0), "",
         "the learned scale replaces the spec sheet's J only once its 1 sigma is below this");
  TQ_NUM("energies.inertia.min_scale", energies.params.inertia.min_scale, open_closed(0.0, 1.0), "",
         "lower bound of the learned scale k");
  TQ_NUM("energies.inertia.max_scale", energies.params.inertia.max_scale, closed(1.0, 10.0), "",
         "upper bound of the learned scale k");
  TQ_NUM("default_oil_temp_c", default_oil_temp_c, closed(-40.0, 200.0), "degC",
         "oil temperature the friction law assumes until OilTemp arrives on CAN");
}

/// Friction (EN-24..36): the law, its prior and what teaches it.
void add_friction(std::vector<SchemaEntry>& t) {
  TQ_BOOL("friction.enabled", friction.enabled, "estimate friction torque (EN-24)");
  t.push_back(fixed_list<4>("estimators.friction.c", TQ_REF(Arr4, estimators.friction.params.c),
                            closed(-1e6, 1e6), "",
                            "C1..C4 of (C1 + C2 n + C3 n^2) e^(C4 t_oil), n rpm, t_oil degC (EN-24)"));
  TQ_BOOL("friction.learn", friction.params.learn, "self-learn at idle and in fuel cut-off (EN-34)");
  TQ_NUM("friction.sign", friction.params.sign, closed(-1.0, 1.0), "",
         "T_fric = sign x polynomial (paper's is negative)");
  TQ_NUM("friction.forgetting", friction.params.forgetting, closed(0.5, 1.0), "",
         "RLS forgetting per observation");
  TQ_NUM("friction.prior_sd_nm", friction.params.prior_sd_nm, open_closed(0.0, 1e6), "N m",
         "prior 1 sigma of each scaled coefficient");
  TQ_INT("friction.min_observations", friction.params.min_observations, closed(1, 1000000), "cycles",
         "motoring cycles before the learned law is valid");
  TQ_NUM("friction.min_rpm", friction.params.min_rpm, closed(0.0, 20000.0), "rpm",
         "observations accepted above this speed");
  TQ_NUM("friction.max_rpm", friction.params.max_rpm, open_closed(0.0, 20000.0), "rpm",
         "and below this speed");
  TQ_NUM("friction.motoring_gate_sigma", friction.params.motoring_gate_sigma, closed(0.0, 1e3), "",
         "once learned, a motoring observation farther than this many sigma from the law (learned_sd_nm with "
         "the law's own spread there) is rejected (0: no gate)");
  TQ_INT("friction.motoring_gate_reaccept", friction.params.motoring_gate_reaccept, closed(1, 1000000),
         "cycles",
         "so many gated observations in a row on the same side are learned from: a real change of friction");
  TQ_NUM("friction.max_load_change_nm", friction.params.max_load_change_nm, open_closed(0.0, 1e4), "N m",
         "skip observations while the measured load moves more than this per segment");
  TQ_BOOL(
      "friction.idle_scales_prior", friction.params.idle_scales_prior,
      "until friction is learned over speed (fuel cut-off with a known load), steady idle with a vehicle's "
      "known load (neutral, the machine alone; not a load signal) scales the whole generic prior law, whose "
      "spread across engines is mostly its level (docs/angle_pipeline.md)");
  TQ_BOOL(
      "friction.learn_at_idle", friction.params.learn_at_idle,
      "learn a local idle correction of the law from the steady-idle friction (off: only C4 learns at idle)");
  TQ_INT("friction.idle_steady_cycles", friction.params.idle_steady_cycles, closed(1, 100000), "cycles",
         "idle observations only after this many cycles of steady idle");
  TQ_NUM("friction.idle_fade_rpm", friction.params.idle_fade_rpm, closed(0.0, 20000.0), "rpm",
         "the idle correction fades linearly from the idle speed to 0 at this speed");
  TQ_BOOL("friction.prior_from_geometry", friction.params.prior_from_geometry,
          "start from the generic Barnes-Moss FMEP correlation scaled by the displacement (Heywood 1988 sec. "
          "13.5) instead of friction.c");
  TQ_NUM("friction.idle_outlier_frac", friction.params.idle_outlier_frac, open_closed(0.0, 10.0), "",
         "idle observations farther than this fraction from the established idle friction are rejected");
  TQ_NUM("friction.idle_max_correction_frac", friction.params.idle_max_correction_frac, closed(0.0, 10.0), "",
         "|idle correction| at most this fraction of the law at idle");
  TQ_INT("friction.idle_after_cut_cycles", friction.params.idle_after_cut_cycles, closed(0, 100000), "cycles",
         "idle observations only this many firing cycles after a fuel cut-off (RLS memory free of coasting "
         "windows)");
  TQ_NUM("friction.idle_max_rls_sd_nm", friction.params.idle_max_rls_sd_nm, open_closed(0.0, 1e4), "N m",
         "idle observations only with an RLS load 1 sigma below this");
  TQ_NUM("friction.idle_speed_tolerance", friction.params.idle_speed_tolerance, open_closed(0.0, 1.0), "",
         "steady idle: cycle-to-cycle speed change below this fraction");
  TQ_NUM("friction.prior_rel_sd", friction.params.prior_rel_sd, open_closed(0.0, 10.0), "",
         "1 sigma of the friction prior, fraction of the friction (until learned); the default is the 68th "
         "percentile of the correlation's error on 12 simulated calibration engines (torque-accuracy "
         "--bed-priors); set it from measured engines of the family when known");
  TQ_NUM("friction.learned_sd_nm", friction.params.learned_sd_nm, open_closed(0.0, 1e4), "N m",
         "1 sigma claimed for the learned friction law");
  TQ_NUM("friction.residual_gain_min", friction.params.residual_gain_min, open_closed(0.0, 1.0), "",
         "step floor of the running 68th percentile of the motoring residuals (the claimed 1 sigma of a "
         "window in fuel cut-off): memory of about its inverse in motoring cycles");
  TQ_NUM("friction.residual_sd_floor_nm", friction.params.residual_sd_floor_nm, open_closed(0.0, 1e3), "N m",
         "the motoring residual scale never claims less than this");
}

/// Per-cylinder torque, misfire and imbalance; the fusion of the brake-torque sources.
void add_cylinder_and_fusion(std::vector<SchemaEntry>& t) {
  TQ_BOOL("cylinder.enabled", cylinder.enabled, "per-cylinder torque, imbalance and misfire");
  TQ_NUM("cylinder.misfire_threshold", cylinder.params.misfire_threshold, open_open(0.0, 1.0), "",
         "misfire when cylinder torque < threshold x cycle mean");
  TQ_NUM("cylinder.imbalance_filter", cylinder.params.imbalance_filter, open_closed(0.0, 1.0), "",
         "EMA weight per cycle of the imbalance (1 = none)");
  TQ_NUM("cylinder.imbalance_tau_s", cylinder.params.imbalance_tau_s, closed(0.0, 60.0), "s",
         "time constant of the imbalance EMA: its weight per cycle is at most 1 - exp(-cycle duration / "
         "tau), the same averaging time at every speed (0: imbalance_filter alone)");
  TQ_NUM("cylinder.min_mean_nm", cylinder.params.min_mean_nm, closed(0.0, 1e4), "N m",
         "no misfire decision below this mean torque");
  TQ_NUM("cylinder.misfire_sigma", cylinder.params.misfire_sigma, closed(0.0, 100.0), "",
         "a misfire's deficit must also exceed this many sigma of the running cycle-to-cycle share noise (0: "
         "off)");
  TQ_NUM("cylinder.share_noise_prior", cylinder.params.share_noise_prior, closed(0.0, 10.0), "",
         "share noise sigma (fraction of the mean) assumed until measured");
  TQ_NUM("cylinder.misfire_after_factor", cylinder.params.misfire_after_factor, closed(0.0, 1.0), "",
         "the segment right after a misfire misses the misfired cylinder's expansion tail: its misfire "
         "threshold is misfire_threshold x this");
  TQ_NUM("cylinder.share_floor_imep_bar", cylinder.params.share_floor_imep_bar, open_closed(0.0, 100.0),
         "bar", "imbalance shares relative to max(cycle-mean work, this IMEP x swept volume per cylinder)");
  TQ_NUM("fusion.max_can_age_s", fusion.max_can_age_s, open_closed(0.0, 60.0), "s",
         "CAN inputs older than this count as lost");
  TQ_BOOL("fusion.blend", fusion.blend,
          "blend agreeing valid sources by inverse variance (false: pick the best)");
  TQ_NUM("fusion.gate_sigma", fusion.gate_sigma, open_closed(0.0, 1e3), "",
         "a source farther than gate_sigma x sigma(difference) from the best is not blended");
  TQ_BOOL("fusion.time_estimate", fusion.time_estimate,
          "use the time chain's UIO brake estimate (Na et al.) as the fusion's lowest-priority source");
  TQ_NUM("fusion.can_load_sd_nm", fusion.can_load_sd_nm, open_closed(0.0, 1e4), "N m",
         "1 sigma of the measured load torque (torque flange / e-machine)");
  TQ_NUM("fusion.brake_sd_ema", fusion.brake_sd_ema, open_closed(0.0, 1.0), "",
         "EMA weight per segment of the measured error variances");
}

/// The fuel-based indicated torque (estimators/energy/fuel_torque.hpp).
void add_fuel(std::vector<SchemaEntry>& t) {
  // Fuel-based indicated torque (estimators/energy/fuel_torque.hpp): efficiency learned while a load
  // reference exists.
  TQ_NUM("fuel.c0_prior", fuel.c0_prior, open_closed(0.0, 1.0), "",
         "prior of c0 in the combustion/heat-loss factor c0 - c1 h (EN-17 eta_ig,ch): combustion and "
         "finite-burn losses only (learned within the prior +- fuel.range_sd sigma)");
  TQ_NUM("fuel.c0_prior_sd", fuel.c0_prior_sd, open_closed(0.0, 0.5), "", "1 sigma of the c0 prior");
  TQ_NUM("fuel.c1_prior", fuel.c1_prior, closed(0.0, 0.5), "",
         "prior of c1: heat-loss share of the ideal work at fuel.ref_rpm and fuel.ref_map_pa (Heywood 12.4 "
         "order of magnitude)");
  TQ_NUM("fuel.c1_prior_sd", fuel.c1_prior_sd, open_closed(0.0, 0.5), "", "1 sigma of the c1 prior");
  TQ_NUM("fuel.p_off_prior_pa", fuel.p_off_prior_pa, closed(-50000.0, 100000.0), "Pa",
         "prior exhaust pressure above ambient at no flow (exhaust p_exh = ambient + p_off + k_bp x^2)");
  TQ_NUM("fuel.p_off_prior_sd_pa", fuel.p_off_prior_sd_pa, open_closed(0.0, 1e5), "Pa",
         "1 sigma of the p_off prior");
  TQ_NUM("fuel.k_bp_prior_pa", fuel.k_bp_prior_pa, closed(0.0, 300000.0), "Pa",
         "prior exhaust back-pressure at the rated flow (x = 1: fuel.rated_rpm at fuel.ref_map_pa): catalyst "
         "and silencer, quadratic in the mass flow");
  TQ_NUM("fuel.k_bp_prior_sd_pa", fuel.k_bp_prior_sd_pa, open_closed(0.0, 3e5), "Pa",
         "1 sigma of the k_bp prior");
  TQ_NUM("fuel.range_sd", fuel.range_sd, closed(1.0, 100.0), "",
         "each learned fuel-model parameter stays within its prior +- this many 1 sigma (a guard against "
         "run-away: the constant pumping term also absorbs constant offsets of the references, e.g. the "
         "learned friction's)");
  TQ_NUM("fuel.kappa", fuel.kappa, open_closed(1.0, 1.67), "",
         "ratio of specific heats of the Otto efficiency 1 - r_c^(1-kappa) (EN-17; 1.3: burned-gas order, "
         "Heywood 5.3)");
  TQ_NUM("fuel.ambient_pa", fuel.ambient_pa, open_closed(0.0, 200000.0), "Pa",
         "ambient pressure of the exhaust (pumping loop)");
  TQ_NUM("fuel.ref_rpm", fuel.ref_rpm, open_closed(0.0, 20000.0), "rpm",
         "reference speed of the heat-loss term h = (ref_rpm/rpm)^a (ref_map/MAP)^b and of the state file's "
         "efficiency");
  TQ_NUM("fuel.ref_map_pa", fuel.ref_map_pa, open_closed(0.0, 400000.0), "Pa",
         "reference MAP of the heat-loss and exhaust-flow terms");
  TQ_NUM("fuel.heat_speed_exp", fuel.heat_speed_exp, closed(0.0, 1.0), "",
         "exponent a of the heat-loss term's speed dependence (Woschni: h_c ~ p^0.8 w^0.8, so the lost share "
         "~ (n p)^-0.2)");
  TQ_NUM("fuel.heat_load_exp", fuel.heat_load_exp, closed(0.0, 1.0), "",
         "exponent b of the heat-loss term's MAP dependence");
  TQ_NUM("fuel.rated_rpm", fuel.rated_rpm, open_closed(0.0, 20000.0), "rpm",
         "speed of the rated exhaust flow (x = rpm/rated_rpm * MAP/ref_map)");
  TQ_NUM("fuel.spark_k_per_deg2", fuel.spark_k_per_deg2, closed(0.0, 0.01), "1/deg^2",
         "spark factor 1 - k (spark - MBT)^2 when the spark advance is on CAN (0.88 at 20 deg from MBT with "
         "3e-4, Heywood fig. 15-13)");
}

/// The fuel model's spark (MBT) terms and how it learns.
void add_fuel_spark_and_learning(std::vector<SchemaEntry>& t) {
  TQ_NUM("fuel.mbt_deg", fuel.mbt_deg, closed(0.0, 60.0), "deg",
         "MBT spark advance at fuel.ref_rpm and full MAP (deg BTDC; textbook part-load order)");
  TQ_NUM("fuel.mbt_per_krpm_deg", fuel.mbt_per_krpm_deg, closed(-20.0, 20.0), "deg",
         "MBT change per 1000 rpm above fuel.ref_rpm (a longer burn in crank angle)");
  TQ_NUM("fuel.mbt_per_vacuum_deg", fuel.mbt_per_vacuum_deg, closed(-30.0, 30.0), "deg",
         "MBT advance added at zero MAP, linear in 1 - MAP/ref_map (a slower burn at part load)");
  TQ_NUM("fuel.model_rel_sd", fuel.model_rel_sd, closed(0.0, 1.0), "",
         "model-form 1 sigma of the fuel model (what no parameter value removes): share of the gross "
         "indicated torque; scaled with the c0, c1, p_off and k_bp prior 1 sigma so that the never-taught "
         "model's 1 sigma covers 68 % of its error on 12 simulated calibration engines (torque-accuracy "
         "--bed-priors)");
  TQ_NUM("fuel.model_rel_sd_learned", fuel.model_rel_sd_learned, closed(0.0, 1.0), "",
         "the same in a speed x MAP cell with fuel.cell_min_references references (they measured part of "
         "it); chosen on the unseen bed's tuning engines");
  TQ_NUM(
      "fuel.forgetting", fuel.forgetting, open_closed(0.9, 1.0), "",
      "RLS forgetting factor per reference cycle (1 = none); the covariance never grows beyond the prior's");
  TQ_NUM("fuel.residual_sd_nm", fuel.residual_sd_nm, open_closed(0.0, 1e4), "N m",
         "measurement 1 sigma of one reference cycle (RLS weight; initial residual sigma)");
  TQ_INT("fuel.min_references", fuel.min_references, closed(1, 1000000), "cycles",
         "reference cycles before the fuel model's residual scale is measured (it is published from its "
         "prior before, with the prior's wide 1 sigma)");
  TQ_INT("fuel.cell_min_references", fuel.cell_min_references, closed(1, 65535), "cycles",
         "references in a speed x MAP cell (4 x 4 grid) before it counts as learned (DaemonStatus, metrics; "
         "no model-form share in its 1 sigma)");
  TQ_INT("fuel.gate_reaccept", fuel.gate_reaccept, closed(1, 1000000), "cycles",
         "once learned, so many references in a row beyond the 5 sigma gate on the same side mean the model "
         "is wrong (learned from a bad reference, or the engine changed): its covariance and residual scale "
         "restart from the prior's and it learns again");
  TQ_NUM("fuel.sd_ema", fuel.sd_ema, open_closed(0.0, 1.0), "",
         "weight of the measured residual variance per reference cycle: EMA weight until valid, then the "
         "floor of a running mean (1/k)");
  TQ_NUM("fuel.fuel_lhv_j_kg", fuel.fuel_lhv_j_kg, open_closed(1e6, 2e8), "J/kg",
         "lower heating value of the fuel (gasoline 43 MJ/kg, Heywood app. D)");
  TQ_NUM("fuel.intake_btdc_deg", fuel.intake_btdc_deg, closed(0.0, 300.0), "deg",
         "intake event (IVC: fuel and charge decided) before firing TDC; a window's fuel and MAP are read "
         "there (IVC 40-60 deg after BDC, Heywood 6.3)");
  TQ_NUM(
      "fuel.work_centroid_atdc_deg", fuel.work_centroid_atdc_deg, closed(0.0, 360.0), "deg",
      "centroid of a cylinder's work after its firing TDC: places each cylinder's combustion in a 720 deg "
      "window (160, tried on the unseen bed's tuning engines only: 130 gives the same result, 190 is worse)");
  TQ_NUM("fuel.report_window_s", fuel.report_window_s, closed(0.0, 0.1), "s",
         "an intake event's fuel cut-off state is revised by a consistent CAN report (flag set with no fuel, "
         "or clear with fuel) this long after it: one period of a 100 Hz ECU frame");
  TQ_NUM("fuel.transient_sd_scale", fuel.transient_sd_scale, closed(0.0, 10.0), "",
         "claimed 1 sigma added (in quadrature) per N m of fuel-model torque spread across a window's intake "
         "events (transients, cut-off edges)");
  TQ_NUM("fuel.sd_floor_nm", fuel.sd_floor_nm, open_closed(0.0, 1e3), "N m",
         "the fuel model's claimed residual scale (68th percentile of |reference residual|) never claims "
         "less than this");
}

/// The tooth-error learner (estimators/learners/tooth_error_learner.hpp).
void add_tooth_learn(std::vector<SchemaEntry>& t) {
  TQ_BOOL("tooth_learn.enabled", tooth_learn.enabled, "apply the per-tooth angle correction table");
  TQ_BOOL("tooth_learn.learn", tooth_learn.params.learn, "learn per-tooth corrections while running");
  TQ_NUM("tooth_learn.max_correction_deg", tooth_max_correction_deg, open_closed(0.0, 5.0), "deg",
         "largest per-tooth correction a stored table may hold (realistic machining: ISO 1328-1 grade 12 "
         "pitch deviation ~0.2 deg); a table beyond it is refused at load and relearned");
  TQ_INT("tooth_learn.min_cycles", tooth_learn.params.min_cycles, closed(1, 100000), "cycles",
         "cycles averaged before the table is used");
  TQ_INT("tooth_learn.fit_harmonics", tooth_learn.params.fit_harmonics, closed(1, 128), "",
         "harmonics of the per-cycle speed fit");
  TQ_INT(
      "tooth_learn.solve_every_cycles", tooth_learn.params.solve_every_cycles, closed(1, 1000), "cycles",
      "solve the table every this many learned cycles (and when it becomes ready, and at each fuel cut-off "
      "cycle); the other cycles only accumulate their fit");
  TQ_NUM("tooth_learn.max_accel_frac", tooth_learn.params.max_accel_frac, open_closed(0.0, 1.0), "",
         "skip cycles whose speed changes more than this fraction");
  TQ_NUM("tooth_learn.min_rpm", tooth_learn.params.min_rpm, closed(0.0, 20000.0), "rpm",
         "learn only above this speed");
  TQ_NUM("tooth_learn.max_rpm", tooth_learn.params.max_rpm, open_closed(0.0, 20000.0), "rpm",
         "and below this speed");
  TQ_NUM("tooth_learn.speed_weight_exp", tooth_learn.params.speed_weight_exp, closed(0.0, 10.0), "",
         "residuals weighted by speed^p");
  TQ_BOOL("tooth_learn.learn_low_orders", tooth_learn.params.learn_low_orders,
          "also learn the per-revolution orders inside the per-cycle fit (from fuel cut-off and the spread "
          "of speeds); false: hold them at the imported table");
  TQ_INT("tooth_learn.min_overrun_cycles", tooth_learn.params.min_overrun_cycles, closed(1, 100000), "cycles",
         "clean fuel cut-off cycles before the overrun identifies a per-revolution order");
  TQ_NUM("tooth_learn.load_slot_frac", tooth_learn.params.load_slot_frac, open_closed(0.0, 0.5), "",
         "firing cycles identify a per-revolution order only against cycles at the same load: MAP within "
         "+-this fraction of the load slot's MAP");
  TQ_NUM("tooth_learn.min_speed_spread_frac", tooth_learn.params.min_speed_spread_frac,
         open_closed(0.0, 10.0), "",
         "a load slot identifies an order when the 1 sigma spread of 1/speed^2 over its cycles exceeds this "
         "fraction of its mean");
  TQ_NUM("tooth_learn.max_low_order_se_frac", tooth_learn.params.max_low_order_se_frac,
         open_closed(0.0, 100.0), "",
         "an order from the speed law is identified only when its intercept's standard error is below this "
         "fraction of the RMS of the learned higher wheel orders");
  TQ_BOOL("tooth_learn.firing_load_law", tooth_learn.params.firing_load_law,
          "an order nothing else identifies is learned from every firing cycle (no fuel cut-off, no two "
          "cycles at the same load): intercept of its per-cycle coefficient against (MAP/100 kPa)/speed^2 "
          "(the engine's ripple scales with the load over the speed squared, the wheel's does not)");
  TQ_BOOL(
      "tooth_learn.spark_column", tooth_learn.params.spark_column,
      "the firing orders' load law gets a column (MAP/100 kPa)/speed^2 * (spark advance - 15 deg) from the "
      "firing cycles with a fresh spark advance on CAN (the combustion's phase, so the ripple's phase at "
      "the firing orders, moves with the spark); without a spark advance the law without it");
  TQ_BOOL("tooth_learn.incycle_sd", tooth_learn.params.incycle_sd,
          "the in-cycle observers' published 1 sigma also carries the tooth table's own standard error (each "
          "firing order's edge-angle standard error read as torque J * speed^2 * order^2 * error); the "
          "estimate is unchanged");
  TQ_NUM("tooth_learn.firing_law_min_load_spread", tooth_learn.params.firing_law_min_load_spread,
         closed(0.0, 1.0), "",
         "the firing orders' load law is used only when this share of the variance of (MAP/100 kPa)/speed^2 "
         "over its cycles is not explained by 1/speed^2 (1 - r^2): loads that vary apart from the speed");
  TQ_INT("tooth_learn.distrust_min_cycles", tooth_learn.params.distrust_min_cycles, closed(1, 100000),
         "cycles",
         "fresh cycles after which an imported (stored) table is checked against the per-tooth evidence of "
         "this run");
  TQ_NUM("tooth_learn.distrust_gate_sigma", tooth_learn.params.distrust_gate_sigma, open_closed(0.0, 1e3), "",
         "an imported table is discarded and relearned when its RMS per-tooth width disagreement with "
         "this run's evidence exceeds this many standard errors of that evidence (and distrust_floor_deg)");
  TQ_NUM("tooth_learn.distrust_floor_deg", tooth_learn.params.distrust_floor_deg, closed(0.0, 5.0), "deg",
         "... and exceeds this RMS width disagreement (well below the ~0.18 deg cumulative pitch deviation "
         "of ISO 1328-1 grade 12)");
}

}  // namespace

void add_estimators(std::vector<SchemaEntry>& t) {
  add_time_estimators(t);
  add_angle_observers(t);
  add_energies(t);
  add_gas_model(t);
  add_friction(t);
  add_cylinder_and_fusion(t);
  add_fuel(t);
  add_fuel_spark_and_learning(t);
  add_tooth_learn(t);
}

}  // namespace torqued::schema_detail
