#pragma once
// Crank-angle-resolved 4-stroke engine simulator with ground truth (docs/simulator.md).
// Not real-time code: it allocates freely. Deterministic: the same Scenario (incl. seed) gives identical
// output. Physics and parameter values: docs/simulator.md.
//
// Angle conventions (shared with the decoder and estimators):
//  - "wheel angle" θ_w: crank angle measured from the first tooth after the gap (tooth 0) of the revolution
//  in
//    which the cam signal rises; 720° cycle = [0, 4π). Cycle k of the output covers θ_w ∈ [4πk, 4π(k+1)).
//  - crank angle after cylinder-1 firing TDC: θ = θ_w − engine.tdc_offset_rad (CrankKinematics' theta720).
//  - tooth index 0 .. 2·teeth−1 within 720°; tooth 0 closes the gap in the cam-phase-0 revolution.
//  - the cam channel is high for wheel angles [cam_rise_deg, cam_fall_deg) of each 720° cycle (default
//  45°..225°).
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "engine_geometry.hpp"
#include "records.hpp"
#include "samples.hpp"

namespace torqued::sim {

/// One point of a piecewise-linear schedule; held constant before the first and after the last point.
struct Breakpoint {
  double t_s = 0.0;
  double value = 0.0;
};
using Schedule = std::vector<Breakpoint>;
[[nodiscard]] double evaluate(const Schedule& schedule, double t_s, double fallback) noexcept;

enum class LoadMode : std::uint8_t {
  kDynoSpeed =
      0,  ///< dynamometer PI controller holds `speed_rpm` (load torque free, may go negative = motoring)
  kTorque = 1,  ///< load torque follows `load_torque_nm` (0 = declutched / free engine)
};
/// From `t_start_s` on, the load works in `mode` (phases sorted by time; the first applies from t = 0).
struct LoadPhase {
  double t_start_s = 0.0;
  LoadMode mode = LoadMode::kDynoSpeed;
};

struct Misfire {
  int cycle = 0;     ///< output cycle index k (the cylinder's firing TDC lies in cycle k)
  int cylinder = 1;  ///< 1-based cylinder number
};

/// Time interval [t_start_s, t_end_s) with fuel cut-off; fuel resumes early when speed < resume_rpm.
struct FuelCut {
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  double resume_rpm = 1000.0;
};

/// Combustion and gas exchange (Wiebe, single-zone first law; docs/simulator.md §2).
struct CombustionParams {
  double gamma = 1.3;               ///< polytropic exponent / ratio of specific heats, IVC..EVO (-)
  double wiebe_a = 5.0;             ///< Wiebe efficiency parameter a (-)
  double wiebe_m = 2.0;             ///< Wiebe form factor m (-)
  double burn_duration_deg = 50.0;  ///< Wiebe duration Δθ (deg)
  double q_lhv_j_kg = 44.0e6;       ///< fuel lower heating value (J/kg)
  double heat_fraction =
      0.80;  ///< fraction of fuel energy released as gas heat (combustion eff. × wall losses)
  double afr_stoich = 14.7;         ///< stoichiometric air/fuel ratio (-)
  double lambda = 1.0;              ///< commanded air/fuel equivalence λ (-)
  double vol_efficiency = 0.85;     ///< volumetric efficiency η_v (-)
  double ivc_deg = 540.0;           ///< IVC, local angle after firing TDC (deg) (= BDC, 180° before TDC)
  double evo_deg = 130.0;           ///< EVO after firing TDC (deg)
  double blowdown_end_deg = 200.0;  ///< end of the exhaust blowdown blend (deg)
  double exhaust_pa =
      105000.0;  ///< exhaust back-pressure (Pa): textbook ambient + system drop (physics),
                 ///< the same figure the estimators take as their prior, neither from the other
};

/// Air path: throttle orifice + manifold filling (docs/simulator.md §3).
struct AirPathParams {
  double ambient_pa = 100000.0;  ///< ambient pressure upstream of the throttle (Pa)
  double manifold_volume_m3 = 2.0e-3;
  double throttle_diameter_m = 0.055;
  double throttle_leak_frac = 0.0025;  ///< closed-throttle leakage as fraction of the full area (-)
  double idle_kp = 2.0e-3;             ///< idle controller: throttle % per rpm of speed error (%/rpm)
  double idle_ki = 1.0e-2;             ///< idle controller integral gain (%/rpm/s)
};

/// Dynamometer / load (docs/simulator.md §4).
struct DynoParams {
  double kp_nm_per_rad_s = 3.0;  ///< speed PI proportional gain (N m / (rad/s))
  double ki_nm_per_rad = 30.0;   ///< speed PI integral gain (N m / rad)
  double speed_filter_s = 0.02;  ///< speed low-pass for the controller (s)
  double torque_lag_s = 0.005;   ///< actuator lag of the load torque (s)
};

/// Sensors (docs/simulator.md §5). All noise seeded from Scenario::seed.
struct SensorParams {
  double tooth_error_sd_deg = 0.05;  ///< per-tooth machining error, 1σ (deg), fixed per wheel
  double jitter_sd_s = 0.3e-6;       ///< edge timestamp jitter, 1σ (s)
  double clock_hz = 50.0e6;          ///< capture clock for timestamp quantisation (Hz); 0 = none
  double cam_rise_deg = 45.0;        ///< cam channel rises at this wheel angle within 720° (deg)
  double cam_fall_deg = 225.0;       ///< and falls here (deg)
  double can_period_s = 0.01;        ///< period of every CAN message (s)
  double can_jitter_s = 0.2e-3;      ///< uniform ± jitter of CAN timestamps (s)
  double can_drop_prob = 0.001;      ///< probability a frame is dropped (-)
  double map_lag_s = 0.010;          ///< first-order lag of the MAP sensor (s)
  double map_noise_pa = 300.0;       ///< MAP noise 1σ (Pa)
  double maf_lag_s = 0.020;          ///< MAF sensor lag (s)
  double maf_noise_frac = 0.01;      ///< MAF noise 1σ, fraction of reading (-)
  double speed_noise_rpm = 2.0;      ///< CAN EngineSpeed noise 1σ (rpm)
  double load_noise_nm = 0.5;        ///< DYNO_1 LoadTorque noise 1σ (N m)
  double load_lag_s = 0.005;         ///< torque-flange measurement lag (s)
  double temp_noise_c = 0.2;         ///< temperature noise 1σ (°C)
  double lambda_noise = 0.005;       ///< lambda sensor noise 1σ (-)
};

/// Friction of the simulated engine (docs/simulator.md §4). Default: the Energies 2019 law (EN-27) that the
/// demo and the built-in scenarios use. The unseen-engines bed (unseen_engines.hpp) draws its own FMEP
/// polynomial instead.
struct FrictionModel {
  bool paper_law = true;             ///< true: EN-27 with the paper's coefficients (fields below unused)
  double fmep0_kpa = 100.0;          ///< FMEP = fmep0 + fmep1 (n/1000) + fmep2 (n/1000)^2, n in rpm (kPa)
  double fmep1_kpa = 15.0;           ///< (kPa per 1000 rpm)
  double fmep2_kpa = 5.0;            ///< (kPa per (1000 rpm)^2)
  double oil_coeff_per_c = -4.0e-3;  ///< FMEP × e^{k (t_oil − oil_ref_c)} (1/°C)
  double oil_ref_c = 90.0;           ///< (°C)
};

/// Electric machine on the crankshaft (hybrid; docs/simulator.md §4). When present it is the load: the torque
/// the load model computes (speed-holding or scheduled) is applied by the machine, through a gear of `ratio`,
/// and EM_1 reports its shaft torque T_em = −T_load / ratio (positive when it drives the crank, i.e.
/// motoring).
struct EMachineSim {
  bool present = false;   ///< false: no machine, no EM_1 frame (the demo and built-in scenarios)
  double ratio = 1.0;     ///< machine speed / crank speed (-)
  double noise_nm = 0.3;  ///< EM_1 EmTorque noise 1σ at the machine shaft (N m)
};

/// Vehicle driveline (docs/simulator.md §4): a clutch, then the vehicle's inertia and road load referred to
/// the crank through the gear and a compliant driveshaft. Clutch closed: the crank sees the shaft torque T_sh
/// = k φ + c (ω − ω_v) (an unknown load to the estimator), J_v ω̇_v = T_sh − T_road, φ̇ = ω − ω_v, and the road
/// load is a PI "driver and terrain" making the engine follow `speed_rpm` (grade, brakes). Clutch open: T_sh
/// = 0 (on closing the vehicle side is synchronised, φ = 0). Accessories (alternator) always load the crank:
/// T_acc = accessory_w / max(ω, 70 rad/s). The load model of the scenario (dynamometer PI or
/// `load_torque_nm`) then acts through the electric machine only (EMachineSim; absent: set load_torque_nm =
/// 0). No DYNO_1 frame: a vehicle has no load signal. VEH_1.ClutchOpen on CAN: it drops `flag_lead_s` before
/// the clutch closes (the TCU knows before the plates touch) and rises `flag_lead_s` after it opened.
struct VehicleSim {
  bool present = false;
  Schedule clutch_closed{};         ///< > 0.5: clutch closed (step schedule) (-); empty: closed throughout
  double j_vehicle_kgm2 = 1.5;      ///< vehicle inertia referred to the crank, m r_w² / i² (kg m²)
  double stiffness_nm_rad = 300.0;  ///< driveline torsional stiffness referred to the crank (N m / rad)
  double damping_nms_rad = 2.5;     ///< driveline damping referred to the crank (N m s / rad)
  double road_kp = 10.0;            ///< road-load PI on the engine speed error (N m / (rad/s))
  double road_ki = 30.0;            ///< (N m / rad)
  double accessory_w = 350.0;       ///< accessories' mechanical power (W)
  double flag_lead_s = 0.05;        ///< VEH_1.ClutchOpen leads the closing / lags the opening by this (s)
  double flag_lag_s = 0.0;          ///< > 0: instead, a late flag: the clutch state of this long ago (s)
  bool flag_on_can = true;          ///< send VEH_1
};

/// Mean-value (Crossley & Cook) mode exists separately (mean_value_engine.hpp, helper "time").
struct Scenario {
  std::string name;
  std::uint64_t seed = 1;
  EngineGeometry engine{};
  WheelGeometry wheel{};
  double duration_s = 3.0;
  double warmup_s = 0.3;                 ///< unrecorded settling before t = 0 with the t = 0 set-points (s)
  double step_deg = 0.1;                 ///< RK4 crank-angle step (deg); must divide 720
  std::vector<LoadPhase> load_phases{};  ///< empty: kDynoSpeed throughout
  Schedule speed_rpm{};                  ///< dyno speed set-point (rpm); also the initial speed
  Schedule load_torque_nm{};             ///< load torque in kTorque mode (N m)
  Schedule throttle_pct{};               ///< throttle position (%); if empty, the ECU follows map_target_kpa
  Schedule map_target_kpa{};             ///< MAP set-point (kPa): throttle from the steady air balance
  Schedule spark_advance_deg{};          ///< spark advance (deg BTDC); empty: built-in map of speed and MAP
  bool idle_control = false;             ///< ECU idle speed controller adds throttle below idle_rpm
  double idle_rpm = 800.0;
  std::array<double, kMaxCylinders> fuel_factor{1, 1, 1, 1,
                                                1, 1, 1, 1};  ///< per-cylinder fuel multiplier (-)
  std::vector<Misfire> misfires{};
  std::vector<FuelCut> fuel_cuts{};
  Schedule oil_temp_c{};  ///< oil temperature (°C); empty: 90
  double coolant_temp_c = 88.0;
  double intake_temp_c = 30.0;
  double spark_offset_deg =
      0.0;  ///< added to the built-in spark map (combustion phasing of another ECU) (deg)
  FrictionModel friction{};
  CombustionParams combustion{};
  AirPathParams air{};
  DynoParams dyno{};
  SensorParams sensors{};
  EMachineSim e_machine{};
  VehicleSim vehicle{};
  int trace_every_steps = 0;  ///< >0: record a FineSample every n integration steps (tests)
};

/// Names of all built-in scenarios, and one by name (throws std::invalid_argument listing the names).
[[nodiscard]] std::vector<std::string> scenario_names();
[[nodiscard]] Scenario scenario_by_name(std::string_view name);

/// Ground truth at one crank-tooth (marking) edge.
struct ToothTruth {
  double t_s = 0.0;            ///< true time of the physical edge (s), before jitter/quantisation
  std::int64_t t_meas_ns = 0;  ///< the same edge as written to edges (jitter + quantisation) (ns)
  int tooth = 0;               ///< 0 .. 2·teeth−1 within 720°
  int cycle = 0;               ///< output cycle index
  double angle720_rad = 0.0;   ///< physical wheel angle of this edge within 720° (nominal + machining error)
  double speed_rad_s = 0.0;    ///< θ̇ at the edge
  double t_ind_nm = 0.0;       ///< Σ gas torque (indicated) (N m)
  std::array<double, kMaxCylinders> t_ind_cyl_nm{};  ///< gas torque per cylinder (index = cylinder − 1)
  double t_mass_nm = 0.0;   ///< reciprocating torque (J − J_rot)θ̈ + ½J'θ̇² (N m)
  double t_fric_nm = 0.0;   ///< friction (N m), positive = loss
  double t_load_nm = 0.0;   ///< dyno / load torque (N m), positive = absorbing
  double t_brake_nm = 0.0;  ///< t_ind − t_fric (crank output) (N m)
};

/// Ground truth per 720° cycle (θ-averages = work / 4π).
struct CycleTruth {
  int cycle = 0;
  double t_start_s = 0.0, t_end_s = 0.0;
  double speed_mean_rad_s = 0.0;  ///< 4π / (t_end − t_start)
  double t_ind_mean_nm = 0.0, t_brake_mean_nm = 0.0, t_fric_mean_nm = 0.0, t_load_mean_nm = 0.0;
  double t_mass_mean_nm = 0.0;
  /// Each cylinder's indicated work / 4π over its own cycle (firing TDC ± 360°) of the combustion in this
  /// cycle.
  std::array<double, kMaxCylinders> cyl_ind_mean_nm{};
  std::array<double, kMaxCylinders> cyl_imep_pa{};  ///< same as IMEP (Pa)
  std::array<double, kMaxCylinders> cyl_peak_pa{};  ///< peak cylinder pressure of that combustion (Pa)
  std::array<double, kMaxCylinders> cyl_fuel_kg{};  ///< injected fuel (kg)
  std::array<bool, kMaxCylinders> misfire{};        ///< injected misfire (not fuel cut)
  bool fuel_cut = false;                            ///< any cylinder of this cycle had its fuel cut
  double map_pa = 0.0;                              ///< true MAP at cylinder-1 IVC (Pa)
  double oil_temp_c = 0.0;
};

/// Fine trace (every trace_every_steps integration steps) for physics tests.
struct FineSample {
  double t_s = 0.0;
  double wheel_angle_rad = 0.0;  ///< cumulative wheel angle (rad)
  double speed_rad_s = 0.0;
  double kinetic_j = 0.0;  ///< ½ J(θ) θ̇²
  double t_ind_nm = 0.0, t_fric_nm = 0.0, t_load_nm = 0.0;
  std::array<double, kMaxCylinders> p_cyl_pa{};
};

struct SimOutput {
  std::vector<EdgeEvent> edges;  ///< channel 0 crank, 1 cam; sorted by t_ns; t = 0 is capture start
  std::array<std::uint8_t, 2> initial_levels{};  ///< crank, cam levels at t = 0
  std::vector<CanFrame> can;                     ///< sorted by t_ns (edge clock, µs resolution), bus 0
  std::vector<ToothTruth> teeth;
  std::vector<CycleTruth> cycles;       ///< complete cycles only
  std::vector<double> tooth_error_rad;  ///< machining error of each physical tooth 0..teeth−1 (rad)
  std::vector<FineSample> trace;        ///< empty unless trace_every_steps > 0
};

/// Nominal marking-edge angle of each physical tooth within one revolution (rad), tooth 0 = 0 for N−M wheels.
[[nodiscard]] std::vector<double> nominal_tooth_angles_rad(const WheelGeometry& wheel);

/// Run the scenario. Throws std::invalid_argument on an inconsistent scenario, std::runtime_error on a stall.
/// `progress`, when set, is called with the simulated time about every 0.5 s of simulation.
[[nodiscard]] SimOutput simulate(const Scenario& scenario,
                                 const std::function<void(double t_s)>& progress = {});

/// Tooth samples as a synced decoder would give them: measured times (machining error + jitter +
/// quantisation), correct tooth index / 720° phase, NOMINAL angle and width (gap tooth: (missing + 1)
/// pitches), dt_s from the previous measured edge. The first sample has synced = false and dt_s = 0.
[[nodiscard]] std::vector<ToothSample> ideal_tooth_samples(const SimOutput& out, const Scenario& scenario);

/// EngineSignals (SI) decoded from the newest CAN frame of each message at or before t_s; a signal is valid
/// when its frame is younger than `max_age_s`.
[[nodiscard]] EngineSignals signals_at(const SimOutput& out, double t_s, double max_age_s = 0.05);

}  // namespace torqued::sim
