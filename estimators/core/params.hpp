#pragma once
// Tuning of every estimator, with the papers' values as defaults. Plain data so that estimators/ stays pure;
// the config loader (config/) fills these from YAML, validates bounds, and documents each key.
// When you add a field here, add its YAML key, bounds and description in config/ as well.
#include <array>

namespace torqued {

/// Na et al. time-triggered estimators (docs/equations.md §1).
struct UioParams {
  double k_s = 0.01;  ///< filter constant k (s) (Na-9, Na-14)
};
struct SlidingModeParams {
  double k_s = 0.01;          ///< output low-pass constant (s) (Na-21)
  double lambda1_nm = 350.0;  ///< switching gain λ1 > sup|τ_e| (N m) (Na-19)
};
struct DirtyDiffParams {
  double k_s = 0.01;  ///< differentiation filter constant (s) (Na-24)
};
struct AdaptiveParams {
  double k_s = 0.01;                        ///< filter constant k (s)
  double ell = 10.0;                        ///< forgetting ℓ (1/s) (Na-45)
  std::array<double, 2> gamma{0.1, 100.0};  ///< Γ diagonal for [speed, air mass flow] (Na-50)
  double kappa = 0.1;                       ///< κ weighting of W2 (Na-50/54)
  bool time_varying_gain = true;            ///< law (Na-52/54) instead of (Na-50)
  std::array<double, 2> k0{10.0,
                           10.0};  ///< K(0) = K0^-1 diagonal entries given as K0 (Na-52), normalised units
  double sigma = 1e-6;  ///< excitation threshold on λ_min(P) of the normalised regressor (Na Remark 9)
  /// Regressor normalisation: φ = [ω·s0, ṁ_air·s1] so both entries are O(1) and Γ, K0, σ are unit-free.
  std::array<double, 2> phi_scale{0.01, 100.0};  ///< s0 (s/rad), s1 (s/kg)
  std::array<double, 2> gamma_tv{20.0, 20.0};  ///< Γ diagonal of law (Na-54) (1/s: K ≈ P^-1 makes Γ a rate)
  double k0_floor = 1e-3;  ///< K^-1 never decays below k0_floor·K0 (bounds K when not excited) (-)
  std::array<double, 2> theta0{0.0, 0.0};  ///< θ̂(0) in normalised units (N m) (paper: 0)
};
struct TimePipelineParams {
  double step_s = 0.001;  ///< time pipeline step T_s (s)
  bool cycle_averaged_speed =
      true;  ///< mean speed over the last 720° (true) or last combustion segment (false)
  double inertia_kgm2 =
      0.0;  ///< J of Na-8 (kg m^2); 0: J_rot + cycle-mean oscillating inertia of the geometry
  double speed_timeout_s = 0.2;  ///< mean speed is stale when the newest tooth is older than this (s)
  bool uio = true;               ///< run the UIO (Na-14)
  bool sliding_mode = true;      ///< run the sliding-mode estimator (Na-21)
  bool dirty_diff = true;        ///< run the dirty-differentiation estimator (Na-24)
  bool adaptive = true;          ///< run the adaptive estimator (Na-50 or Na-54, see AdaptiveParams)
};

/// Per-tooth pre-processing shared by the angle estimators (speed, low-pass, small Kalman filter for θ̈; EN
/// §2.1).
struct PreprocessParams {
  double lowpass_hz =
      300.0;  ///< first-order low-pass cut-off on tooth speed (Hz) (EN §2.1 uses a 300 Hz FIR)
  double accel_jerk_sd = 2.0e5;  ///< white-jerk intensity of the [θ̇, θ̈] Kalman filter (rad/s^3/sqrt(s))
  double edge_noise_deg = 0.005;  ///< residual edge-angle error after tooth-error learning, 1σ (deg)
  double jitter_s = 0.3e-6;       ///< edge timestamp jitter, 1σ (s)
};
/// Chauvin angle-domain estimators (docs/equations.md §2).
/// The burn-phasing learner of the in-cycle model (estimators/learners/burn_phase_learner.hpp): an offset
/// added to the gas model's burn centroid so that the model's firing-order phase agrees with the Kalman's
/// estimate's (docs/angle_estimators.md (7)).
struct BurnPhaseParams {
  bool learn = true;  ///< learn the offset and apply it to the in-cycle gas model's burn centroid (the
                      ///< tuning rule of docs/angle_estimators.md (7), with tooth_learn.spark_column)
  double gain = 1.0;  ///< integrator gain: offset step = −gain × the cycle's phase difference (deg/deg)
  double max_step_deg = 0.5;      ///< largest offset step per used cycle (deg)
  double min_offset_deg = -12.0;  ///< learned offset bounds (deg of burn centroid, later positive)
  double max_offset_deg = 12.0;
  double min_ripple_nm =
      5.0;                  ///< model's firing-order ripple amplitude below which a cycle is not used (N m)
  int quality_cycles = 10;  ///< time constant of the mean phase difference deciding "converged" (cycles)
  double converged_deg = 0.25;  ///< |mean phase difference| at or below which the offset is converged (deg)
  int min_cycles = 20;          ///< used cycles before "converged" may be reported
};

struct KalmanParams {
  double delta = 3.0;         ///< coloured-noise pole δ (1/rad) of h(z) (CK-18)
  double model_delta = 16.0;  ///< coloured-noise pole δ (1/rad) while the gas model is valid (the model-miss
                              ///< set; delta serves the papers' filter): 1/δ the crank angle over which the
                              ///< model's miss stays correlated (16: 3.6°; chosen with model_torque_sd_nm and
                              ///< the Wiebe burn on the bed's tuning engines, docs/angle_estimators.md "A
                              ///< pole of its own")
  double torque_sd_nm = 300.0;       ///< stationary 1σ of the net torque x2 under h(z); sets Q (N m), used
                                     ///< while the gas model is not valid (no MAP yet) or gas_model is false
  double model_torque_sd_nm = 20.0;  ///< the same with the gas model valid, where x2 is only what the
                                     ///< pressure model misses (tuned on the bed's tuning engines with the
                                     ///< spark-phased Wiebe model, with model_delta: the least fresh-start +
                                     ///< transient + cut-off total whose claimed 1σ still covers >= 68 % of
                                     ///< the teeth; docs/angle_estimators.md "A pole of its own")
  double edge_noise_deg = 0.01;  ///< edge-angle error used for R (deg) (0.05 unlearned wheel, ~0.01 learned:
                                 ///< tuned on incycle_*_65 + fuel_cut, 0.005/0.01/0.02 tried)
  double jitter_s = 0.3e-6;      ///< timestamp jitter used for R (s)
  int smoother_lag = 10;  ///< output x2(n-lag | n), 0..12 teeth (fixed-lag smoother; 0 = paper's predictor).
                          ///< 10, not 6: at 4000-6000 rpm jitter makes R large, the filter's memory outgrows
                          ///< 6 teeth and the phase lag returned (7° at 6000 rpm; 2-3° with 10)
  bool periodic_gains = true;  ///< use precomputed asymptotic periodic gains (APS) instead of exact Riccati
  bool differenced_edge_noise = true;  ///< edge errors enter a period as the difference of its two edges
                                       ///< (MA(1) noise, two states); false = white R as in the paper
  bool gas_model = true;    ///< the pipeline feeds a cylinder-pressure model's gas torque ripple as a known
                            ///< input (set_model_torque); false = the paper's zero-mean prior
  double min_rpm = 500.0;   ///< lowest speed of the APS gain schedule (rpm)
  double max_rpm = 8000.0;  ///< highest speed of the APS gain schedule (rpm)
  int speed_bins = 32;      ///< APS gain sets, log-spaced in speed, interpolated (R depends on speed)
  BurnPhaseParams burn_phase{};  ///< the gas model's burn-phasing learner (run by the angle chain)
};
struct FourierParams {
  int harmonics = 12;  ///< n_h (CF §V.B); 4-cyl fires at i = 4: keep 4, 8, 12 and the imbalance sub-harmonics
  double l_ke = 6.0;   ///< L_ke (1/rad)
  double l_a0 = 0.3;   ///< L_a0 (1/rad^2)
  double l_ref = 0.07;  ///< L_ref: l_{a_i} = l_{b_i} = i L_ref (1/rad^2), while the gas model is not valid
  double model_l_ref = 0.0175;  ///< L_ref with the gas model valid: the coefficients carry only the model's
                                ///< miss (tuned on incycle_*_65 + fuel_cut: 0.07/0.035/0.0175 and
                                ///< gain_ref_rpm 1500 tried)
  bool gas_model = true;        ///< the pipeline feeds the cylinder-pressure model's gas torque ripple
  int output_lag =
      0;  ///< report T̂ at tooth k−lag from the coefficients after tooth k (0..6; latency, less noise)
  double gain_ref_rpm =
      3000.0;  ///< >0: coefficient gains × min(1, (gain_ref_rpm/rpm)²), keeping the noise of the energy
               ///< innovation (∝ θ̇²) constant above that speed; 0 = fixed gains as in the paper.
               ///< 3000, not 1500: the coefficients followed too slowly at 3000-6000 rpm and in a
               ///< coast-down (tuned on incycle_*_65 + fuel_cut: 1500/2500/3000/3500/4500/0 tried)
};

/// Energies 2019 chain (docs/equations.md §3).
/// Learning the crankshaft inertia from a known load (estimators/learners/inertia_learner.hpp). The spec
/// sheet's J (engine.j_rot_kgm2) is a drawing or catalogue figure: the flywheel, clutch or damper fitted can
/// differ by ±10 % or more, and the cycle balance's J·θ̈ term carries that error straight into the friction
/// learned in a decelerating fuel cut-off and into the brake torque of every transient.
struct InertiaParams {
  bool learn = true;           ///< learn a scale k (J = k·J_spec) while a load signal is present (-)
  double prior_rel_sd = 0.15;  ///< 1σ of the spec-sheet J, fraction (catalogue vs fitted flywheel) (-)
  double min_step_nm = 3.0;  ///< a cycle pair counts only when Δ(J_spec θ̈) between them exceeds this (N m)
  double obs_sd_nm = 1.5;    ///< 1σ of one pair's torque residual (CAN load lag, fuel-model steps) (N m)
  double gate_sigma = 4.0;   ///< pairs farther than this many σ from the current fit are rejected (-)
  double max_fuel_change = 0.02;      ///< firing pairs: fuel per injection within this fraction (-)
  double max_map_change_pa = 2000.0;  ///< and MAP within this (Pa)
  double apply_max_sd = 0.03;  ///< k replaces the spec sheet's J only once its 1σ is below this; before,
                               ///< a few pairs could swing it by ±8 % and every transient with it (-)
  double min_scale = 0.6;      ///< bounds of k (-)
  double max_scale = 1.6;
};

struct EnergiesParams {
  double window_start_btdc_deg = 50.0;  ///< RLS window start before TDC (deg)
  double window_end_btdc_deg = 20.0;    ///< RLS window end before TDC (deg)
  double polytropic_kappa = 1.3;        ///< κ for compression/expansion (-)
  double rls_forgetting = 0.995;        ///< RLS forgetting factor per window (-) (memory ≈ 10 cycles)
  double lowpass_hz = 300.0;            ///< speed pre-filter cut-off (Hz)
  double eso_omega0 = 20.0;             ///< ESO bandwidth ω0 (rad/s) (EN-23)
  double fuel_lhv_j_kg = 43e6;          ///< q_LHV (J/kg)
  double eso_base_efficiency =
      0.75;                     ///< η_ign·η_ig,ch at the nominal point; ΔE_ff (ESO state) corrects it (-)
  double ivc_abdc_deg = 0.0;    ///< intake valve closing after BDC: start of polytropic compression (deg)
  double evo_atdc_deg = 130.0;  ///< exhaust valve opening after firing TDC: end of polytropic expansion (deg)
  double blowdown_end_atdc_deg =
      200.0;  ///< cylinder pressure reaches the exhaust pressure here (cosine blend) (deg)
  double exhaust_pressure_pa =
      105000.0;                      ///< exhaust back-pressure, for the pumping loop in fuel cut-off (Pa):
                                     ///< physics, not tuning: ambient 1.013 bar + a typical 0.04 bar exhaust
                                     ///< system drop at part load (Heywood ch. 6); configurable per engine
  double ivc_pressure_factor = 1.0;  ///< p_IVC = factor × MAP (volumetric-efficiency correction) (-)
  bool model_expansion_cylinder = true;  ///< model the cylinder that fired 180° earlier in the RLS window (-)
  bool rls_estimate_inertia = false;  ///< regress [θ̈, 1] (paper) instead of [1] with the known J_rot (-)
  int rls_min_windows = 120;          ///< windows before the RLS load is reported converged (-)
  int rls_window_shifts = 5;  ///< each window also shifted 1..n−1 teeth earlier (telescoping noise average)
  double burn_centroid_atdc_deg = 10.0;  ///< heat release lumped here in the expansion-pressure closure when
                                         ///< the spark advance is unknown (deg after TDC)
  double burn_delay_deg = 29.0;     ///< spark to equivalent burn centroid (deg): centroid = delay − advance
  double burn_duration_deg = 55.0;  ///< in-cycle gas torque model only (Kalman known input): the
                                    ///< heat release spread over this angle around the burn centroid
                                    ///< (the RLS closure keeps the lumped burn); 0 = lumped. 55 with the
                                    ///< Wiebe shape (40 with the raised cosine before; tuning engines,
                                    ///< docs/angle_estimators.md "A pole of its own")
  double burn_wiebe_a = 5.0;        ///< in-cycle model only: burn shape a Wiebe function with this efficiency
                                    ///< parameter a instead of the raised cosine (0 = raised cosine) (-)
  double burn_wiebe_m = 2.0;        ///< and this form factor m (Heywood §9.2.1: a = 5, m = 2) (-)
  double incycle_compression_kappa = 0.0;  ///< in-cycle model only: κ of compression (0 = polytropic_kappa)
  double incycle_expansion_kappa = 0.0;    ///< in-cycle model only: κ of the burned gas's expansion (0 =
                                           ///< polytropic_kappa). Burned-gas γ is 1.2-1.3 (Heywood ch. 4);
                                           ///< 1.25 helps the unseen bed, worsens the demo: not the default
                                           ///< (docs/angle_estimators.md)
  /// In-cycle model only: its burn centroid follows the spark advance, burn_delay_deg − advance, as the RLS
  /// closure's (false: fixed at burn_centroid_atdc_deg, as before); docs/angle_estimators.md
  bool incycle_spark_phasing = true;
  double energy_window_deg = 30.0;    ///< kinetic energy averaged over this window around each boundary (deg)
  double segment_offset_deg = -20.0;  ///< segment boundary relative to each firing TDC (deg, <0: before TDC)
  double idle_max_rpm = 1100.0;       ///< idle (friction C4 learning) below this mean speed (rpm)
  double idle_max_load_nm = 3.0;      ///< and with |load| below this (N m)
  double cycle_ke_window_deg =
      120.0;  ///< 720° balance (brake/indicated): KE averaged over this window ending
              ///< energy_window/2 after boundary 0; jitter noise ∝ 1/window; 0: off (deg)
  double cylinder_window_deg =
      60.0;  ///< per-cylinder segment work (shares, imbalance, misfire) only: KE averaged
             ///< over this window ending energy_window/2 after each boundary; jitter and
             ///< tooth-table noise ∝ 1/window; < 720°/cylinders; 0: energy_window (deg)
  double cylinder_window_taper = 1.0;  ///< that window's tooth weights 1 − taper·(2x − 1)², x the place in
                                       ///< it (0: rectangle; 1: parabola, the edge jitter spread over all
                                       ///< edges: 6000 rpm balanced pattern 2.2/1.7/1.2 → 1.5/1.5/0.9 pp) (-)
  double rls_change_threshold =
      4.0;  ///< crank-only load change: CUSUM of the per-firing load innovations (in σ)
            ///< above this re-seeds the RLS at the cycle mean (0: RLS alone) (-)
  double rls_step_min_sd_nm = 1.0;  ///< floor of the innovations' 1σ (N m)
  double rls_change_max_sd_nm =
      6.0;                  ///< no load-change tracking while the cycle mean's steady 1σ exceeds this (N m)
  InertiaParams inertia{};  ///< inertia learned from a known load (inertia_learner.hpp)
  double can_load_latency_s =
      0.010;  ///< the CAN load torque lags the flange by this (sensor lag + half the frame
              ///< period); the energy balance takes each tooth's load this much later (s)
};
/// The Energies 2019 paper's friction law of its own test engine (EN-24 coefficients). An example of one
/// engine, never a default: the simulator's reference engine uses it too, so a default taken from it would
/// make our tables right and other engines wrong. torque-accuracy --paper-friction starts from it for
/// comparison.
inline constexpr std::array<double, 4> kEnergiesPaperFrictionC{-23.86, 2.45e-3, -5.20e-6, -4.67e-3};

struct FrictionParams {
  /// T_fric = (C1 + C2 n + C3 n²) e^{C4 t_oil}, n in rpm, t_oil in °C (EN-24). The starting point only when
  /// prior_from_geometry is false; then the user gives the engine's own law (no default engine is assumed).
  std::array<double, 4> c{0.0, 0.0, 0.0, 0.0};
  /// Start from the generic Barnes-Moss FMEP correlation scaled by the displacement (friction_learner.hpp),
  /// not from `c`: nothing of one particular engine is assumed until friction is learned.
  bool prior_from_geometry = true;
  double idle_outlier_frac =
      0.35;  ///< idle observations farther than this fraction from the current friction
             ///< at idle are rejected (counted) once the idle level is established (-)
  double idle_max_correction_frac = 0.5;  ///< |idle correction| ≤ this fraction of the law at idle (-)
  int idle_after_cut_cycles = 25;   ///< idle observations only this many firing cycles after a fuel cut-off,
                                    ///< so that the RLS memory holds no coasting windows (cycles)
  double idle_max_rls_sd_nm = 1.5;  ///< and only with an RLS load 1σ below this (tight, settled) (N m)
  double idle_speed_tolerance = 0.03;  ///< steady idle: cycle-to-cycle speed change below this fraction (-)
  double prior_rel_sd = 0.27;          ///< 1σ of the generic prior, fraction of the friction (-): the 68th
                                       ///< percentile of its error on 12 simulated calibration engines
                                       ///< (torque-accuracy --bed-priors; docs/angle_pipeline.md)
  double learned_sd_nm = 2.0;          ///< 1σ claimed for the learned friction law (N m)
  double residual_gain_min =
      0.02;  ///< once learned, the motoring residuals' 68th percentile (the claimed 1σ of
             ///< a window in fuel cut-off) is a running estimate with this step floor (-)
  double residual_sd_floor_nm = 0.1;  ///< that scale never claims less (N m)
  bool learn = true;                  ///< self-learn at idle and in fuel cut-off (EN-34)
  double sign = -1.0;                 ///< T_fric = sign·(...): the paper's polynomial is negative (-)
  double forgetting = 0.998;          ///< RLS forgetting factor per observation (-)
  double prior_sd_nm = 20.0;          ///< prior 1σ of each scaled coefficient (N m) (-)
  int min_observations = 20;          ///< motoring cycles before the learned law is reported valid (-)
  double min_rpm = 500.0;             ///< observations accepted between min_rpm ..
  double max_rpm = 7000.0;            ///< .. and max_rpm (rpm)
  bool idle_scales_prior = true;      ///< until learned over speed, steady idle with a known load scales the
                                      ///< whole generic law (its spread across engines is mostly its level)
  bool learn_at_idle = true;    ///< learn a local idle correction from the steady-idle friction (RLS load at
                                ///< zero load) below the motoring range (off: idle only learns C4)
  int idle_steady_cycles = 10;  ///< idle observations only after this many cycles of steady idle (-)
  double idle_fade_rpm = 1500.0;  ///< the idle correction fades linearly from the idle speed to 0 here (rpm)
  double motoring_gate_sigma =
      4.0;  ///< once learned, a motoring observation farther than this many σ of its
            ///< prediction (learned_sd_nm ⊕ the law's own spread there) is rejected (-)
  int motoring_gate_reaccept = 10;  ///< .. unless this many in a row disagree the same way: a real change (-)
  double max_load_change_nm = 1.0;  ///< skip observations while the measured load moves more than this per
                                    ///< segment (the CAN load lags the flange; dyno transients) (N m)
};
struct CylinderParams {
  double misfire_threshold = 0.5;  ///< misfire when a cylinder's torque < threshold × cycle mean (-)
  double imbalance_filter = 0.2;   ///< EMA weight per cycle of the published imbalance (1 = no filter) (-)
  double imbalance_tau_s = 0.5;  ///< and at most 1 − exp(−T_cycle/τ): the same time constant at every speed
                                 ///< (0.2 per cycle is 0.6 s at 1000 rpm, 0.1 s at 6000 rpm, where the jitter
                                 ///< noise of a share grows as ω²); 0: the per-cycle weight alone (s)
  double min_mean_nm = 5.0;  ///< no misfire decision while the median segment-mean torque is below this (N m)
  double misfire_sigma = 4.0;  ///< a misfire's deficit must also exceed this many σ of the running share
                               ///< noise (0: off) (-)
  double share_noise_prior = 0.15;  ///< share noise σ (fraction of the mean) assumed until measured: with
                                    ///< misfire_sigma 4 a misfire needs a 60 % deficit at first (a missing
                                    ///< combustion is ~100 %) (-)
  double misfire_after_factor =
      0.5;  ///< the segment right after a misfire misses the misfired cylinder's expansion tail (EVO at
            ///< 120-160° ATDC reaches into the next segment: up to half of a firing segment's work on an
            ///< I6's 120° segments): its misfire threshold is misfire_threshold × this (-)
  double share_floor_imep_bar =
      0.5;  ///< imbalance shares are relative to max(cycle-mean work, this IMEP × swept
            ///< volume per cylinder): below any firing idle (1-2 bar net IMEP), so a small
            ///< or negative mean (overrun, idle after cut-off) cannot blow the shares up (bar)
};
/// Fused brake torque for the torque-split controller (docs/equations.md §4; rule in torque_fusion.hpp).
struct FusionParams {
  double max_can_age_s = 0.1;  ///< CAN inputs older than this count as lost (s)
  bool blend = false;          ///< blend agreeing valid sources by inverse variance (false: pick the best)
  double gate_sigma =
      3.0;  ///< a source farther than gate_sigma·σ(difference) from the best is not blended (-)
  bool time_estimate = false;   ///< the time chain's UIO brake estimate is the fusion's external source
  double can_load_sd_nm = 0.5;  ///< 1σ of the measured load torque (torque flange / e-machine) (N m)
  double brake_sd_ema =
      0.05;  ///< EMA weight per segment of the measured error variances (≈ 20-segment memory) (-)
};
struct ToothLearnParams {
  bool learn = true;       ///< learn per-tooth angle corrections
  int min_cycles = 20;     ///< cycles averaged before the table is used (demo: 20 instead of 50 brings the
                           ///< in-cycle Kalman at 800-1500 rpm from 60-130 % to ≈ 10 % of p2p 3 s earlier)
  int fit_harmonics = 12;  ///< per-cycle smooth fit of the speed waveform: harmonics of the 720° cycle (-).
                           ///< 12, not 8: the firing order 6/rev (I4) was left to the per-tooth residual,
                           ///< which then held the engine ripple of that order
  int solve_every_cycles = 8;    ///< the table (orders, residual, width ratios) is solved every this many
                                 ///< learned cycles (and at the cycle that makes it ready and at each fuel
                                 ///< cut-off cycle); the other cycles only accumulate their fit (cycles)
  double max_accel_frac = 0.05;  ///< skip cycles whose speed changes by more than this fraction (-)
  double min_rpm = 600.0;        ///< learn only above this speed (rpm)
  double max_rpm = 7000.0;       ///< and below this one (rpm)
  double speed_weight_exp = 4.0;  ///< residuals weighted by speed^p (ripple ∝ 1/speed²): high speeds dominate
  bool learn_low_orders =
      true;  ///< also learn the per-revolution orders the per-cycle fit absorbs (below
             ///< fit_harmonics/2 per rev) from what identifies them: fuel cut-off cycles
             ///< and/or the spread of speeds (wheel part speed-independent, ripple ∝ 1/speed²)
  int min_overrun_cycles = 8;  ///< clean fuel cut-off cycles (whole cycle and the one before cut) needed
                               ///< before the overrun identifies a per-revolution order (cycles)
  double load_slot_frac =
      0.02;  ///< the speed law compares firing cycles at the SAME load only: a load slot holds
             ///< cycles whose MAP is within ±this fraction of the slot's MAP (the ripple scales
             ///< with the load, so a load that changes with speed would fake an intercept) (-)
  double min_speed_spread_frac =
      0.10;  ///< a slot identifies an order when the 1σ spread of 1/speed² over its cycles
             ///< exceeds this fraction of its mean (was a fixed 0.20; 0.10 chosen looking
             ///< at the demo recording, whose load slots span less speed) (-)
  double max_low_order_se_frac =
      0.05;  ///< variance check: an order is identified only when the standard error of its
             ///< intercept (from the scatter of the cycles about the 1/speed² law) is below
             ///< this fraction of the RMS of the learned higher orders of the wheel (-)
  bool firing_load_law =
      true;  ///< an order nothing else identifies is learned from ALL steady firing cycles
             ///< (any load): intercept against u = (MAP/100 kPa)/ω̄² (ToothOrderSource::kFiring)
  bool spark_column =
      true;  ///< the firing orders' load law gets a column u·(spark − spark_ref) from the firing cycles with
             ///< a fresh spark advance (the combustion's phase, so the ripple's firing-order phase, moves
             ///< with the spark); without a spark advance the law [1, u, x] (docs/angle_estimators.md (6);
             ///< on with the burn-phasing learner, (7))
  bool incycle_sd =
      false;  ///< the in-cycle observers' published 1σ also carries the table's own standard error: the
              ///< firing orders' edge-angle standard errors (ToothOrderId::edge_se_rad) read as torque
              ///< J·ω̄²·r²·ε_r (wheel_table_accel_var; docs/angle_estimators.md (11)); output only
  double firing_law_min_load_spread =
      0.05;  ///< the firing orders' load law [1, u, x] (x = 1/ω̄²) is used only when this share of the
             ///< variance of u is not explained by x (1 − r²): loads that vary apart from the speed. At
             ///< one load u ∝ x and the law loses the speed drift the same-load slots model (-)
  // An imported (persisted) table is checked against what the engine shows: the fresh per-tooth residual
  // above the fit's orders (the part a table holds per tooth, learned independently of the import) against
  // the imported table's part there. Disagreeing beyond both gates, the import is discarded and relearned.
  int distrust_min_cycles = 10;      ///< fresh cycles before the check (cycles)
  double distrust_gate_sigma = 4.0;  ///< RMS disagreement beyond this many standard errors of the fresh
                                     ///< mean (from the cycles' scatter) (-)
  double distrust_floor_deg =
      0.05;  ///< and beyond this RMS width disagreement (deg): well below the
             ///< 0.18 deg cumulative pitch deviation of ISO 1328-1 grade 12 (60 teeth)
};

}  // namespace torqued
