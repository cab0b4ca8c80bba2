#pragma once
// The angle pipeline: every angle-domain method, run per crank tooth (docs/architecture.md data flow).
// Constructed from the engine/wheel geometry and the tuning structs, sized at construction; on_tooth() is
// real-time safe (no allocation, no locks, no exceptions, no I/O).
//
// Per tooth:   speed, acceleration (ToothPreprocessor); in-cycle indicated torque from the Chauvin TV-Kalman
//              (APS gains) and Fourier observers (helper "angle"), each given the latest extended load
//              T_load + T_fric of this pipeline so that they report T_ind (CK eq. (1), CF eq. (1)).
// Per segment (one per firing, rolling 720° window ending at the segment boundary):
//   brake      = Δ(½Jθ̇²)/4π + load (CAN)                          [CycleEnergy, no friction model needed]
//   indicated  = brake + learned friction, or crank-only Δ(½Jθ̇²)/4π + RLS extended load
//   friction   = FrictionLearner law at the cycle's mean speed and oil temperature
//   load       = CAN load (or RLS extended load − friction when CAN is lost)
//   fused      = TorqueFusion of {energy+CAN, crank-only, ESO, external}
// Per cycle:   per-cylinder indicated torque, imbalance, misfire (CylinderTorque).
// Load:        everywhere above, "load" is the net load on the crank, T_load − T_em,crank when an electric
//              machine's torque is on CAN (fold_e_machine, e_machine.hpp): a known input of every balance.
// Learning:    friction C1..C3 from fuel cut-off cycles and from motoring by the electric machine (energy
// balance
//              + measured net load + modelled pumping loop),
//              C4 at idle from the RLS extended load (= friction when the load is zero).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>

#include "chauvin_kalman.hpp"
#include "cycle_energy.hpp"
#include "cycle_ke_window.hpp"
#include "cylinder_torque.hpp"
#include "e_machine.hpp"
#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "fourier_observer.hpp"
#include "friction_learner.hpp"
#include "fuel_torque.hpp"
#include "indicated_eso.hpp"
#include "inertia_learner.hpp"
#include "load_reference.hpp"
#include "load_rls.hpp"
#include "methods.hpp"
#include "params.hpp"
#include "samples.hpp"
#include "time_pipeline.hpp"
#include "tooth_preprocessor.hpp"
#include "torque_fusion.hpp"

namespace torqued {

struct AnglePipelineConfig {
  EngineGeometry engine{};
  WheelGeometry wheel{};
  EnergiesParams energies{};
  FrictionParams friction{};
  CylinderParams cylinder{};
  FusionParams fusion{};
  PreprocessParams preprocess{};
  KalmanParams kalman{};
  FourierParams fourier{};
  FuelTorqueParams fuel{};
  EMachineParams e_machine{};      ///< hybrid input: machine torque folded into the net load (e_machine.hpp)
  LoadReferenceParams load_ref{};  ///< vehicle: clutch / neutral flags, accessory prior (load_reference.hpp)
  bool run_kalman = true;          ///< Chauvin TV-Kalman in-cycle indicated torque per tooth
  bool run_fourier = true;         ///< Chauvin Fourier observer per tooth (disabled if its gains fail CF-14)
  double default_oil_temp_c = 90.0;  ///< used until an oil temperature arrives on CAN (°C)
  /// A spark advance can arrive (its CAN signal is mapped): else the in-cycle gas model's spark-phased
  /// tables are not built (LoadRls::ripple_first/last), as it never reads them.
  bool spark_on_can = true;
};

/// Per-tooth output.
struct ToothOutput {
  std::int64_t t_ns = 0;
  int tooth = 0;
  double angle_rad = 0.0;       ///< edge angle within 720° from tooth 0 (rad)
  double speed_rad_s = 0.0;     ///< w/dt of the period ending here (rad/s)
  double accel_rad_s2 = 0.0;    ///< θ̈ from the pre-processor's [θ̇, θ̈] Kalman filter (rad/s²)
  double speed_lp_rad_s = 0.0;  ///< low-passed speed (rad/s)
  TorqueEstimate
      kalman_ind;  ///< Chauvin TV-Kalman T̂_ind; its t_ns is the edge it refers to (fixed-lag smoother)
  TorqueEstimate fourier_ind;  ///< Fourier observer T̂_ind at this edge
  bool valid = false;
};

/// Which ToothOutput member carries which in-cycle EstimatorTorque method: the angle stage emits the
/// registry's in-cycle methods (idl/methods.hpp, domain kAngleInCycle, in its order) through this table, each
/// stamped with its estimate's own t_ns; an in-cycle entry without a row fails the build
/// (publish/angle_stage.cpp).
struct InCycleMethodOutput {
  std::uint8_t method = 0;
  TorqueEstimate ToothOutput::*estimate = nullptr;
};
inline constexpr InCycleMethodOutput kInCycleMethodOutputs[] = {
    {torque_METHOD_KALMAN, &ToothOutput::kalman_ind},
    {torque_METHOD_FOURIER, &ToothOutput::fourier_ind},
};

/// Per-segment output (rolling 720° means), with the per-cylinder record refreshed once per cycle.
struct CycleOutput {
  std::int64_t t_ns = 0;           ///< time of the tooth that completed the segment (ns)
  std::uint32_t seq = 0;           ///< segments reported since reset
  int boundary = 0;                ///< boundary index (0: cylinder-1 segment starts: a full cycle ended)
  bool cycle_end = false;          ///< boundary == 0: `cylinders` is new
  double speed_mean_rad_s = 0.0;   ///< 4π / duration of the 720° window (rad/s)
  TorqueEstimate brake;            ///< best brake torque of the pipeline's own methods (N m)
  TorqueEstimate indicated;        ///< best indicated torque (N m)
  TorqueEstimate friction;         ///< friction at the window's speed and oil temperature (N m)
  TorqueEstimate load;             ///< load torque: CAN, or RLS extended load − friction (N m)
  TorqueEstimate brake_energy;     ///< Δ(½Jθ̇²)/4π + CAN load (N m)
  TorqueEstimate indicated_crank;  ///< Δ(½Jθ̇²)/4π + RLS extended load (N m), crank only
  TorqueEstimate load_rls;         ///< RLS extended load T_load + T_fric (N m)
  TorqueEstimate indicated_eso;    ///< ESO (N m)
  ReferenceKind reference =
      ReferenceKind::kNone;  ///< what fixed the window's load (kNone: nothing, or mixed)
  FusedTorque fused;
  CylinderCycle cylinders;
};

struct AnglePipelineStats {
  std::uint64_t teeth = 0;
  std::uint64_t not_synced = 0;
  std::uint64_t invalid = 0;          ///< rejected samples (non-finite, out-of-range tooth)
  std::uint64_t sequence_breaks = 0;  ///< missing teeth (windows spanning them were dropped)
  std::uint64_t segments = 0;
  std::uint64_t cycles = 0;
  std::uint64_t friction_observations = 0;
  std::uint64_t inertia_observations = 0;  ///< cycle pairs the inertia learner learned from
  std::uint64_t misfires = 0;
  std::uint64_t free_coasts = 0;  ///< fuel cut-offs recognised as a free coast-down (detect_free_coast)
};

class AnglePipeline {
 public:
  static constexpr std::uint8_t kToothReady = 1;
  static constexpr std::uint8_t kSegmentReady = 2;
  static constexpr std::uint8_t kCycleReady = 4;

  explicit AnglePipeline(const AnglePipelineConfig& config);

  void reset() noexcept;
  /// Real-time safe. Returns a mask of k*Ready flags telling which outputs are new.
  std::uint8_t on_tooth(const ToothSample& s, const EngineSignals& sig) noexcept;

  /// Optional external brake estimate for the fusion (e.g. the time pipeline's UIO); used at the next
  /// segment.
  void set_external(const FusionSource& src) noexcept { external_ = src; }

  /// Whether the wheel's tooth table is learned (or imported): until it is, the in-cycle observers and the
  /// per-cylinder record say so in their health. Default: learned (no learner in use).
  /// Feedback (6) of the angle chain: the burn-phasing learner's offset of the in-cycle gas model's burn
  /// centroid (deg, + = later; BurnPhaseLearner), added to the spark-phased centroid
  /// (energies.incycle_spark_phasing). Real-time safe; takes effect at the next tooth.
  void set_burn_offset_deg(double offset_deg) noexcept {
    if (offset_deg == burn_offset_deg_) return;
    burn_offset_deg_ = offset_deg;
    ripple_pair_ok_ = false;  // the centroid's table pair is recomputed
  }
  [[nodiscard]] double burn_offset_deg() const noexcept { return burn_offset_deg_; }
  void set_wheel_learned(bool learned) noexcept {
    cyl_.set_wheel_learned(learned);
    kalman_.set_wheel_learned(learned);
    fourier_.set_wheel_learned(learned);
  }

  /// The applied tooth table's own uncertainty (wheel_table_accel_var, rad²; 0: none): the in-cycle Kalman's
  /// published 1σ gains J̄·ω̄²·√var in quadrature (docs/angle_estimators.md (11)); its estimate does not
  /// change. Real-time safe; kept through reset() (the chain sets it where it applies the table).
  void set_wheel_table_var(double accel_var) noexcept {
    wheel_accel_sd_ = std::isfinite(accel_var) && accel_var > 0.0 ? std::sqrt(accel_var) : 0.0;
  }
  [[nodiscard]] const ToothOutput& tooth_output() const noexcept { return tooth_; }
  [[nodiscard]] const CycleOutput& cycle_output() const noexcept { return cycle_; }
  [[nodiscard]] const AnglePipelineStats& stats() const noexcept { return stats_; }
  [[nodiscard]] FrictionLearner& friction() noexcept { return friction_; }
  [[nodiscard]] const FrictionLearner& friction() const noexcept { return friction_; }
  [[nodiscard]] const LoadRls& load_rls() const noexcept { return rls_; }
  /// The in-cycle Kalman observer (diagnostics: its innovation and gain per tooth).
  [[nodiscard]] const ChauvinKalman& kalman() const noexcept { return kalman_; }
  /// Fuel-based indicated torque (learned efficiency; persisted with friction, see FuelTorqueState).
  /// J = scale · J_spec, learned from a known load (InertiaLearner); persisted like the friction law.
  [[nodiscard]] InertiaLearner& inertia() noexcept { return inertia_; }
  [[nodiscard]] const InertiaLearner& inertia() const noexcept { return inertia_; }
  [[nodiscard]] FuelTorque& fuel_model() noexcept { return fuel_; }
  [[nodiscard]] const FuelTorque& fuel_model() const noexcept { return fuel_; }
  /// Measured variance of the compression-window chain's indicated torque vs the energy balance (N m²).
  [[nodiscard]] double crank_error_var() const noexcept { return crank_err_var_; }
  void import_crank_error_var(double v) noexcept {
    if (std::isfinite(v) && v >= 0.0) crank_err_var_ = v;
  }
  [[nodiscard]] const AnglePipelineConfig& config() const noexcept { return cfg_; }
  /// The gas model's ripple handed to the in-cycle observers on the last tooth (N m; diagnostics).
  [[nodiscard]] double last_ripple_nm() const noexcept { return last_ripple_nm_; }
  /// The in-cycle gas model's burn centroid now (deg after firing TDC).
  [[nodiscard]] double ripple_centroid_deg() const noexcept;

 private:
  [[nodiscard]] double gas_ripple_nm(int k, bool works_ok) const noexcept;
  std::uint8_t break_sequence(ToothSample s) noexcept;
  void on_segment(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh) noexcept;
  // on_segment's steps, in order, and its gates (each gate is one named condition of the learning rules).
  void count_fuel_state(const EngineSignals& sig, bool can_fresh) noexcept;
  void segment_work(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh,
                    CycleOutput& o) noexcept;
  /// Extended load T_load + T_fric of a segment (N m): measured load + friction, else the RLS; false if
  /// neither.
  [[nodiscard]] bool segment_load_star(const SegmentEnergy& seg, const TorqueEstimate& rls,
                                       double& load_star_nm) const noexcept;
  /// Indicated work of a cyl_energy_ segment (J); false if the segment or its load is not usable.
  [[nodiscard]] bool cylinder_work(const SegmentEnergy& seg, double& work_j) const noexcept;
  /// A cyl_energy_ segment ended: its work to CylinderTorque; a completed cycle goes into cycle_.cylinders.
  void cylinder_segment(const SegmentEnergy& seg, double work_j, bool ok) noexcept;
  void cycle_balance(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh, double dke_nm,
                     const FuelWindow& fw, CycleOutput& o) noexcept;
  void learn(const SegmentEnergy& seg, const EngineSignals& sig, bool can_fresh, double dke_nm,
             const FuelWindow& fw, const CycleOutput& o) noexcept;
  void fuse(const SegmentEnergy& seg, const EngineSignals& sig, CycleOutput& o) noexcept;
  void learn_inertia(const SegmentEnergy& seg, bool can_fresh, double dke_spec_nm, const FuelWindow& fw,
                     const CycleOutput& o) noexcept;
  [[nodiscard]] bool motoring_observation_allowed(const CycleReference& ref, const EngineSignals& sig,
                                                  bool load_steady) const noexcept;
  [[nodiscard]] bool idle_observation_allowed(const SegmentEnergy& seg, const CycleReference& ref,
                                              const TorqueEstimate& rls, double rpm,
                                              bool cycle_end) const noexcept;
  [[nodiscard]] bool rests_on_accessory_prior(const CycleReference& ref) const noexcept;
  [[nodiscard]] bool fuel_learning_allowed(const CycleReference& ref, const EngineSignals& sig,
                                           bool can_fresh, bool cycle_end,
                                           const FuelWindow& fw) const noexcept;
  void learn_fuel(const CycleReference& ref, const EngineSignals& sig, bool can_fresh, const FuelWindow& fw,
                  const CycleOutput& o) noexcept;
  [[nodiscard]] FuelPoint fuel_point(const EngineSignals& sig, bool can_fresh, double rpm) const noexcept;
  [[nodiscard]] TorqueEstimate fuel_prior_brake(std::int64_t t_ns, double fric,
                                                double fric_sd) const noexcept;
  bool fuel_model_slot(const CycleOutput& o, FusionSource& z) const noexcept;
  [[nodiscard]] bool crank_agrees_with_fuel(const CycleOutput& o) const noexcept;
  [[nodiscard]] bool fuel_reference_allowed(const CycleReference& ref, const EngineSignals& sig,
                                            bool can_fresh, bool load_steady, bool cycle_end) const noexcept;
  [[nodiscard]] double friction_sd_nm(double fric) const noexcept;
  /// What fixes the load of the 720° window ending at `seg`, for the learners (one decision, see .cpp).
  [[nodiscard]] CycleReference cycle_reference(const SegmentEnergy& seg) const noexcept;
  /// 1σ of the load in the balance: the measured load's, or the reference kind's when larger (N m).
  [[nodiscard]] double load_sd_nm() const noexcept {
    return std::max(cfg_.fusion.can_load_sd_nm, ref_sd_nm_);
  }
  /// Per tooth: the load reference now, and how long its kind has held.
  void track_reference(const LoadReference& ref, bool load_ok) noexcept;

  AnglePipelineConfig cfg_;
  CycleEnergy energy_;
  CycleKeWindow wide_;  ///< wide KE window for the 720° balance (energies.cycle_ke_window_deg)
  /// Per-cylinder segment work only (CylinderTorque): KE windows of energies.cylinder_window_deg ending where
  /// energy_'s end, so they complete on the same tooth; energy_ keeps driving everything else.
  CycleEnergy cyl_energy_;
  LoadRls rls_;
  FrictionLearner friction_;
  InertiaLearner inertia_;
  /// The previous cycle end, for the inertia learner's pairs of consecutive cycles.
  struct InertiaPoint {
    bool ok = false, fired = false, cut = false;
    double dke_spec_nm = 0.0, load_nm = 0.0, rpm = 0.0, fuel_kg = 0.0, map_pa = 0.0;
  };
  InertiaPoint prev_inertia_{};
  /// Free coast-down without a flag (detect_free_coast): the last fully fired cycle, and whether the current
  /// fuel cut-off was recognised as the engine coasting alone.
  struct CoastFired {
    double dke_nm = 0.0, t_ind_nm = 0.0;
    int age = 1 << 20;          ///< cycle ends since it
    double coast_dke_nm = 0.0;  ///< the last cut-off cycle's deceleration torque while a free coast holds
  };
  CoastFired coast_fired_{};
  bool free_coast_ = false;
  /// True when this window ends a free coast (its load is then not known).
  bool detect_free_coast(const FuelWindow& fw, double dke_nm, const CycleOutput& o) noexcept;
  /// Guards of detect_free_coast (not tunables): a torque below this (N m) is too small to form a ratio with;
  /// the entry decision is taken within so many cycles of the last fully fired one.
  static constexpr double kCoastMinTorqueNm = 1.0;
  static constexpr int kCoastEntryCycles = 2;
  [[nodiscard]] bool free_coast_allowed() const noexcept;
  void free_coast_reference(bool cut_now, double rpm, double map_pa, LoadReference& lref) noexcept;
  /// The coast passed the cycle-to-cycle test once: only then is its load known (a speed-held dynamometer
  /// passes the entry tests and fails the next cycle's: no window of it is published with the accessories'
  /// load).
  bool coast_confirmed_ = false;
  bool coast_idle_ = false;  ///< the free coast goes on as idle (fuel back on)
  double coast_resume_rpm_ = 0.0, coast_resume_map_pa_ = 0.0;  ///< speed and MAP when the fuel came back
  IndicatedEso eso_;
  FuelTorque fuel_;
  TorqueEstimate fuel_ind_{};  ///< model-based indicated torque of the window: fuel model, motored in cut-off
  /// Fuel, MAP and cut-off flag at each cylinder's intake event: the fuel model of a window is evaluated on
  /// the events whose work lies in it (FuelAngleWindow).
  FuelAngleWindow fuel_win_;
  [[nodiscard]] FuelWindow fuel_window(const SegmentEnergy& seg) const noexcept;
  /// on_tooth's in-cycle observer step: this tooth's load reference into `lref`, then the Kalman filter and
  /// the Fourier observer fed; returns whether the net load is known on fresh CAN (see .cpp).
  [[nodiscard]] bool feed_incycle_observers(const ToothSample& s, const EngineSignals& sig, bool works_ok,
                                            bool can_fresh, LoadReference& lref) noexcept;
  /// The extended load handed to the in-cycle Kalman at this tooth (N m).
  [[nodiscard]] double observer_load_star_nm(double net_load_nm, bool load_ok) const noexcept;
  /// The gas ripple handed to the in-cycle observers, with the fuel-state change rule (updates cut_flag_).
  /// `fresh`: the CAN values are fresh at this tooth (on_tooth's can_fresh).
  [[nodiscard]] double observer_ripple_nm(const ToothSample& s, const EngineSignals& sig, bool works_ok,
                                          bool fresh) noexcept;
  double crank_err_var_ =
      0.0;             ///< measured variance of the compression-window chain vs the energy balance (N m²)
  bool fired_ = true;  ///< current segment fires (no fuel cut-off flag, not motored by the machine)
  bool machine_motoring_ = false;  ///< at the last tooth: the machine drives the crank with no fuel injected
  ReferenceKind ref_kind_ = ReferenceKind::kNone;  ///< at the last tooth (kNone: load unknown there)
  double ref_sd_nm_ = 0.0;                         ///< its 1σ; the largest since the kind last changed (N m)
  int ref_teeth_ = 0;                              ///< teeth since the kind last changed
  CylinderTorque cyl_;
  TorqueFusion fusion_;
  ToothPreprocessor pre_;
  ChauvinKalman kalman_;
  FourierObserver fourier_;
  bool wide_done_ = false;     ///< wide_ completed on the current tooth
  bool fourier_ok_ = false;    ///< gains passed check_stability() at construction
  double load_star_nm_ = 0.0;  ///< latest extended load handed to the in-cycle observers (N m)
  /// Fuel-state change rule of the in-cycle observers' gas model (observer_ripple_nm): the ECU cut-off flag
  /// at the last tooth, and the firing positions whose work was measured since it last changed (bit per
  /// position).
  bool cut_flag_ = false;
  double last_ripple_nm_ = 0.0;  ///< last_ripple_nm()
  double wheel_accel_sd_ = 0.0;  ///< √wheel_table_accel_var of the applied table (rad; set_wheel_table_var)
  double j_mean_kgm2_ = 0.0;     ///< cycle-mean crank inertia J̄ of the specification (kg m²)
  /// Output only: the table's standard error read as torque, J̄·ω̄²·√var, joins a published 1σ in quadrature.
  void add_table_sd(TorqueEstimate& e) const noexcept {
    const double w = tooth_.speed_lp_rad_s;
    if (wheel_accel_sd_ > 0.0 && e.uncertainty > 0.0)
      e.uncertainty = std::hypot(e.uncertainty, j_mean_kgm2_ * w * w * wheel_accel_sd_);
  }
  /// The in-cycle model's combustion phasing (energies.incycle_spark_phasing): the table pair around the
  /// current burn centroid (ripple_t_, ripple_t_ + 1; ripple_p3b_ the second's p3), and fired_p3_'s table.
  mutable int ripple_t_ = LoadRls::kRippleBase;
  mutable std::array<double, kMaxCylinders> ripple_p3b_{};
  /// The table pair and weight (LoadRls::ripple_table) for the held spark advance of these bits: looked up
  /// again only when the advance changes (ripple_pair_ok_ false after reset()).
  mutable std::uint64_t ripple_pair_spark_ = 0;
  mutable bool ripple_pair_ok_ = false;
  mutable int ripple_pair_t_ = LoadRls::kRippleBase;
  mutable double ripple_pair_f_ = 0.0;
  int fired_t_ = LoadRls::kRippleBase;
  std::uint32_t works_since_fuel_change_ = ~0u;
  std::array<double, kMaxCylinders> fired_p3_{};  ///< combustion p3 per position when the cut-off began (Pa)
  bool have_fired_p3_ = false;

  ToothOutput tooth_;
  CycleOutput cycle_;
  AnglePipelineStats stats_;
  FusionSource external_{};
  std::array<double, kMaxCylinders> cyl_work_j_{};  ///< last indicated work per firing position (J)
  /// gas_ripple_nm()'s p3 per position for the held MAP and works' validity it was computed at; invalid
  /// (ripple_p3_ok_ false) once a work changes. The pipeline is one thread's.
  mutable std::array<double, kMaxCylinders> ripple_p3_{};
  mutable double ripple_p3_map_ = 0.0;
  mutable bool ripple_p3_works_ = false, ripple_p3_ok_ = false;
  std::array<bool, kMaxCylinders> cyl_work_ok_{};
  bool works_all_ok_ = false;                        ///< all_works_ok(), kept where cyl_work_ok_ changes
  [[nodiscard]] bool all_works_ok() const noexcept;  ///< every firing position has a measured work
  double oil_c_ = 90.0;
  double prev_speed_ = 0.0, prev_dt_ = 0.0;
  bool have_prev_ = false;
  int cut_segments_ = 0;        ///< consecutive segments in fuel cut-off
  int fired_segments_ = 0;      ///< consecutive segments firing
  int since_cut_segments_ = 0;  ///< firing segments since the last fuel cut-off (large: none seen)
  int idle_steady_cycles_ = 0;  ///< consecutive cycles at steady idle (speed ±3 %, load steady)
  double prev_cycle_rpm_ = 0.0;
  double brake_var_ = 4.0;  ///< running variance of segment-to-segment brake changes (N m²)
  double prev_brake_ = 0.0;
  bool have_prev_brake_ = false;
  double prev_load_ = 0.0;    ///< previous window's mean CAN load (N m)
  double held_map_pa_ = 0.0;  ///< last fresh MAP (Pa), held while CAN is lost
  bool have_map_ = false;
  double burn_offset_deg_ = 0.0;  ///< set_burn_offset_deg (deg)
  double held_spark_deg_ = 0.0;   ///< last fresh spark advance (deg), NaN until one arrived
  bool have_prev_load_ = false;
};

}  // namespace torqued
