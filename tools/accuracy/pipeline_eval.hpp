#pragma once
// Runs simulator scenarios through the AnglePipeline and compares every output with the simulator's truth.
// Shared by the torque-accuracy tool and the estimator tests (not real-time code; allocates freely).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "angle_pipeline.hpp"
#include "engine_sim.hpp"
#include "params.hpp"
#include "unseen_engines.hpp"

namespace torqued::eval {

/// Tooth widths handed to the pipeline.
enum class ToothTable {
  kNone,     ///< nominal widths (machining error uncorrected)
  kTrue,     ///< the simulator's true machining errors ("perfectly learned": comparison only)
  kLearned,  ///< ToothErrorLearner table learned on a warm-up recording of the same wheel (warmup_scenario())
};

struct EvalOptions {
  ToothTable tooth_table = ToothTable::kLearned;
  ToothLearnParams tooth_learn{};                 ///< learner tuning for kLearned
  std::optional<std::array<double, 4>> friction;  ///< import these friction coefficients before the run
  /// Start here when `friction` is empty ("not told"); empty: the generic correlation from the geometry
  /// (FrictionParams::prior_from_geometry).
  std::optional<std::array<double, 4>> friction_prior = std::array<double, 4>{0.0, 0.0, 0.0, 0.0};
  std::optional<std::array<double, 2>>
      idle_correction;                        ///< import [correction N m, idle rpm] after `friction`
  std::optional<FuelTorqueState> fuel_state;  ///< import this learned fuel-model state
  std::optional<double> crank_err_var;  ///< import this measured compression-window chain variance (N m²)
  std::optional<EngineGeometry>
      spec_engine;                ///< configure the pipeline with this geometry (spec sheet), not the truth
  bool score_all_cycles = false;  ///< score brake/indicated on every cycle after skip, whatever their health
  double load_lost_after_s = -1.0;  ///< >= 0: the load-torque signal (only) disappears from this time on
  int skip_cycles = 12;             ///< cycles ignored at the start (RLS / ESO convergence)
  double can_lost_after_s = -1.0;   ///< >= 0: CAN signals disappear from this time on
  double steady_pct = 3.0, steady_nm = 2.0;  ///< steady-state tolerances
  double transient_pct = 5.0, transient_nm = 3.0;
  AnglePipelineConfig base{};  ///< tuning (engine/wheel are taken from the scenario)
  EMachineParams
      e_machine{};  ///< hybrid input: bound = the EM_1 machine torque is used (scenario with a machine)
  bool no_fuel_cutoff_flag = false;  ///< the ECU sends no cut-off flag: fuel mass 0 is all there is
  /// In-cycle beds (incycle_bed.hpp): write the per-tooth truth, gas model ripple and Kalman estimate to this
  /// CSV file (empty: none): the fresh start's (incycle_dump), the transient and cut-off run's
  /// (incycle_regimes_dump). Columns: docs/eval.md.
  std::string incycle_dump;
  std::string incycle_regimes_dump;
};

/// One compared cycle (the pipeline's rolling 720° window ending at boundary 0).
struct CycleCompare {
  double t_s = 0.0;
  bool transient = false;
  double speed_rpm = 0.0;
  double brake = 0.0, brake_true = 0.0;
  double indicated = 0.0, indicated_true = 0.0;
  double friction = 0.0, friction_true = 0.0;
  double load_rls = 0.0, load_star_true = 0.0;  ///< extended load T_load + T_fric
  double indicated_crank = 0.0, indicated_eso = 0.0, fused = 0.0;
  double brake_sd = 0.0, indicated_sd = 0.0, fused_sd = 0.0;  ///< claimed 1σ (N m)
  bool friction_prior = false;                                ///< the friction law still rested on the prior
  FusionQuality quality = FusionQuality::kInvalid;
  bool brake_valid = false, indicated_valid = false, rls_valid = false, eso_valid = false;
};

struct ErrorStats {
  int n = 0;
  int pass = 0;  ///< cycles within tolerance
  double max_abs_nm = 0.0;
  double rms_nm = 0.0;
  double max_rel_pct = 0.0;  ///< max |err| / |truth| (%)
  double worst_ratio = 0.0;  ///< max |err| / allowed (≤ 1: all pass)
  int covered = 0;           ///< cycles with |err| ≤ claimed 1σ (when a σ was given)
  int with_sd = 0;           ///< cycles that carried a claimed 1σ
};

struct ScenarioResult {
  std::string name;
  int cycles = 0;
  double mean_rpm = 0.0;
  ErrorStats brake, indicated, fused, brake_crank, indicated_crank, indicated_eso, friction, load_rls;
  double imbalance_max_pp = 0.0;  ///< |filtered imbalance − true imbalance| max over cylinders (pp)
  std::array<double, kMaxCylinders> imbalance_est{}, imbalance_true{};
  int misfires_true = 0, misfires_found = 0, misfires_false = 0;
  int detection_cycles = 0;  ///< cycles with a per-cylinder record
  int detection_active = 0;  ///< of which misfire detection was possible (MisfireDetection::kActive)
  std::array<double, 4> friction_coefficients{};
  double idle_correction_nm = 0.0, idle_rpm = 0.0;  ///< learned idle correction at the end of the run
  FuelTorqueState fuel_state{};                     ///< learned fuel-model state at the end of the run
  double crank_err_var = 0.0;
  std::uint64_t friction_observations = 0;
  std::vector<CycleCompare> rows;
  AnglePipelineStats stats;
  double tooth_resid_deg = 0.0;  ///< RMS(width correction used − true width error) over the teeth (deg)
  double tooth_edge_resid_deg = 0.0;     ///< RMS of the edge-angle residual (cumulative, mean removed) (deg)
  std::uint64_t tooth_learn_cycles = 0;  ///< warm-up cycles the learner used (kLearned)
  bool tooth_low_orders = false;         ///< learner separated the firing orders (kLearned)
};

/// Warm-up recording for the tooth-error learner: the same engine, wheel (machining errors come from the
/// seed) and sensors as `scenario`, steady plateaus 1000/2000/3000/4000 rpm at mid load (firing) then a fuel
/// cut-off coast-down, as the daemon sees over its first minutes of life. Misfires and the scenario's
/// schedules removed.
[[nodiscard]] sim::Scenario warmup_scenario(const sim::Scenario& scenario);

/// Learned tooth table of the scenario's wheel: width ratio (true/nominal) per physical tooth (cached per
/// seed, engine and wheel). `cycles`/`low_orders` (optional) report the learner's state.
std::vector<double> learned_width_ratios(const sim::Scenario& scenario, const ToothLearnParams& params,
                                         std::uint64_t* cycles = nullptr, bool* low_orders = nullptr);

/// Simulate `scenario` and evaluate the pipeline on it.
/// The pipeline configuration of an evaluation: options.base with the scenario's (or the spec sheet's) engine
/// and wheel, and the friction prior (options.friction_prior, else the generic correlation by displacement).
AnglePipelineConfig pipeline_config(const sim::Scenario& scenario, const EvalOptions& options);
ScenarioResult evaluate(const sim::Scenario& scenario, const EvalOptions& options);
/// Same on an already simulated output.
ScenarioResult evaluate(const sim::Scenario& scenario, const sim::SimOutput& out, const EvalOptions& options);

/// One engine of the unseen-engines bed: configured from its spec sheet only, friction from the
/// generic prior, learned on bed_learning_run(), then bed_eval_run() evaluated from that learned state with
/// and without the load-torque signal (other CAN signals stay). Brake/indicated scored on every cycle after
/// `skip_cycles`.
struct BedResult {
  std::string engine;
  bool report = false;
  ScenarioResult learn, with_load, without_load;
};
BedResult evaluate_bed_engine(const sim::BedEngine& engine, const EvalOptions& options, bool short_run);

/// Hybrid input on the bed: the engine's recordings with an electric machine of `ratio` as the
/// load. learn: the learning recording with the machine as the known sole load (no dynamometer signal);
/// with_machine: the evaluated recording without load signal, machine bound (sole load); control: the same
/// recording, machine torque present on CAN but not bound (crank-only).
struct BedMachineResult {
  std::string engine;
  ScenarioResult learn, with_machine, control;
};
BedMachineResult evaluate_bed_e_machine(const sim::BedEngine& engine, const EvalOptions& options,
                                        bool short_run, double ratio);
/// Motoring by the machine as the friction reference: friction of the evaluated recording (no load signal,
/// nothing learned during it) from the generic prior (`prior`) and after learning on bed_motoring_run()
/// (`learned`). Friction scored within 10 % or 2 N m.
struct BedMotoringResult {
  std::string engine;
  ScenarioResult motoring, prior, learned;
};
BedMotoringResult evaluate_bed_motoring(const sim::BedEngine& engine, const EvalOptions& options,
                                        bool short_run, double ratio);

/// The fuel model on the bed without a load signal (the vehicle): fused brake torque of the evaluated
/// recording scored within 8 % or 5 N m, its claimed 1σ's coverage and the published share.
struct BedFuelRun {
  int cycles = 0;                  ///< scored cycles
  int published = 0;               ///< of which the fused value was published (quality not invalid)
  int prior_only = 0;              ///< of which with quality prior_only
  int pass = 0;                    ///< published within 8 % or 5 N m
  int covered = 0;                 ///< published with |error| <= claimed 1σ
  int covered2 = 0;                ///< published with |error| <= 2 × claimed 1σ
  double rms_nm = 0.0;             ///< RMS error of the published fused values (N m)
  double rms_pct = 0.0;            ///< that RMS / RMS of the true brake torque (%)
  double bias_nm = 0.0;            ///< mean error of the published fused values (N m)
  std::vector<CycleCompare> rows;  ///< the evaluated recording's cycles
  std::uint32_t references = 0;    ///< fuel-model references it rested on
  std::uint16_t cells = 0;         ///< learned speed × MAP cells (bit mask)
};
struct BedFuelResult {
  std::string engine;
  BedFuelRun one_point;  ///< learned on bed_one_point_learning_run() (load signal), evaluated without it
  BedFuelRun never;      ///< nothing learned, no load signal anywhere
  double with_load_rms_nm = 0.0;  ///< fused RMS with the load signal from the one-point state (N m)
};
BedFuelResult evaluate_bed_fuel(const sim::BedEngine& engine, const EvalOptions& options, bool short_run);

/// Learn friction on the "fuel_cut" coast-down, then on "demo", starting at the prior; returns the
/// coefficients.
std::array<double, 4> learn_friction(const EvalOptions& options);

}  // namespace torqued::eval
