#pragma once
// Friction self-learning (Energies 2019 eq. (EN-24)..(EN-36)).
//   T_fric = s · (C1 + C2 n + C3 n²) · e^{C4 t_oil},  n in rpm, t_oil in °C, s = FrictionParams::sign.
// The paper prints coefficients whose polynomial is negative over 800-6000 rpm (it reports friction as a
// negative, decelerating torque); `sign = -1` (default) turns them into a positive friction torque.
// Learning, both by recursive least squares (EN-34):
//  - C1..C3 from "motoring" observations: in fuel cut-off J θ̈ = −T_fric − T_load (+ pumping), so one cycle's
//    energy balance yields T_fric at that speed (the caller forms the observation, see AnglePipeline).
//    Regressor φ = s e^{C4 t_oil} [1, n/1000, (n/1000)²] (scaled for conditioning), forgetting factor, and
//    prior covariance around the starting coefficients so that a narrow speed range cannot run away.
//  - C4 at idle: T_fric = T_ind, so Δ ln T_fric = C4 Δt_oil between idle observations at different oil
//    temperatures (EN-30..33); scalar RLS on the pairs. Without oil-temperature variation C4 stays at its
//    prior.
//  - Idle correction (learn_at_idle): motoring never reaches idle (fuel resumes at ≈ 1100 rpm), so the
//  quadratic
//    is extrapolated there (≈ 1.2 N m off on the simulator). Fitting the idle point into C1..C3 tilts the
//    whole quadratic (a correction Δ at 800 rpm moves 4000 rpm by ≈ 7Δ). Instead the steady-idle friction
//    (EN-30: T_fric = T_ind at zero load) sets a LOCAL additive correction δ = T_idle − law(n_idle) (running
//    mean), applied fully at and below the idle speed and faded linearly to 0 at idle_fade_rpm. It is not
//    persisted (the four coefficients are); it is relearned after idle_steady_cycles of steady idle in each
//    run.
//  - Prior level at idle (idle_scales_prior): until the law is learned over speed (no motoring observation,
//    nothing imported) it is the generic correlation, whose spread across engines is mostly its level (±27 %
//    of the whole curve, prior_rel_sd), not its shape. A steady-idle observation with a known load (neutral,
//    the machine alone) then measures that level: s = T_idle / law(n_idle), combined with the prior s = 1 ±
//    prior_rel_sd by inverse variances (scalar Bayesian update). The observation's 1σ (its load reference's
//    and the RLS load's) is shared by every idle cycle (an accessory prior does not average out), so it is
//    counted once: the level's 1σ never goes below it. The law is scaled by s everywhere; the first motoring
//    observation folds s into the coefficients, from where the RLS continues. Not persisted (like the idle
//    correction, relearned at idle in each run).
// Coefficients can be exported and imported for persistence across restarts (the daemon writes them
// atomically).
#include <array>
#include <cstdint>

#include "coverage_scale.hpp"
#include "estimate.hpp"
#include "params.hpp"

namespace torqued {

/// Generic prior of the EN-24 coefficients from the swept volume: the Barnes-Moss correlation of total
/// friction mean effective pressure of warm 4-stroke SI engines (845-2000 cm³), as given in J. B. Heywood,
/// "Internal Combustion Engine Fundamentals", McGraw-Hill 1988, §13.5:
///   fmep [bar] = 0.97 + 0.15 (N/1000) + 0.05 (N/1000)²,  N in rpm,
/// and the mean friction torque of a 4-stroke engine T_fric = fmep · V_d / 4π. Stroke enters through V_d only
/// (the Patton-Nitschke-Heywood / Sandoval-Heywood models add mean-piston-speed terms: a finer prior, not
/// used here). C4 = 0 (the correlation is for a warm engine; the oil-temperature law is learned at idle).
/// Returned in the learner's units for the given `sign` (C = T / sign).
[[nodiscard]] std::array<double, 4> generic_friction_prior(double displacement_m3, double sign) noexcept;

class FrictionLearner {
 public:
  explicit FrictionLearner(const FrictionParams& params) noexcept;

  /// Back to the configured (or last imported) coefficients, forgetting the learning history.
  void reset() noexcept;

  /// Motoring observation (fuel cut-off): friction torque `friction_nm` measured at `speed_rpm`,
  /// `oil_temp_c`. Returns false (and counts) when rejected: non-finite, outside the speed range, or (once
  /// learned) farther than motoring_gate_sigma σ from the law's prediction, σ² = learned_sd_nm² + φᵀPφ (the
  /// law's own spread there, large where it was never learned), so one bad cycle cannot move the law;
  /// motoring_gate_reaccept such rejections in a row on the same side are taken as a real change and learned
  /// from. Real-time safe.
  /// `obs_var_nm2`: the observation's variance (N m²) from its load reference (load_reference.hpp); the RLS
  /// weighs it 1 / max(1, obs_var_nm2) (its unit variance is 1 N m², a measured load's balance); its 1σ also
  /// bounds the law's claimed 1σ from below (reference_sd_nm; 0: a noise-free reference, tests).
  bool observe_motoring(double speed_rpm, double oil_temp_c, double friction_nm,
                        double obs_var_nm2 = 0.0) noexcept;

  /// Idle observation: friction torque equals the indicated torque (no load). Learns C4 from oil-temperature
  /// differences. Returns false when rejected. Real-time safe.
  /// `scale_prior`: the observation may scale the prior law's level (see above; the pipeline passes true for
  /// a vehicle's references, whose idle may be all it gets, and false with a load signal, whose coast-downs
  /// teach the whole law: the dynamometer case stays as it was). `obs_sd_nm`: its 1σ (its load reference's
  /// and the RLS load's; 0: learned_sd_nm), which weighs that update.
  bool observe_idle(double speed_rpm, double oil_temp_c, double friction_nm, bool scale_prior = false,
                    double obs_sd_nm = 0.0) noexcept;

  /// Level s of the generic law learned at idle (1: none), while the law is not learned over speed.
  [[nodiscard]] double prior_level() const noexcept { return level_active() ? level_ : 1.0; }
  /// 1σ of the law's level as a fraction: prior_rel_sd before any idle observation, the posterior after;
  /// while the law is not learned over speed this is the friction's claimed relative 1σ.
  [[nodiscard]] double prior_level_sd() const noexcept;

  /// T_fric (N m) at the given speed and oil temperature (law + faded idle correction). Real-time safe (one
  /// exp()).
  [[nodiscard]] double friction_nm(double speed_rpm, double oil_temp_c) const noexcept;
  /// The EN-24 law alone (no idle correction).
  [[nodiscard]] double law_nm(double speed_rpm, double oil_temp_c) const noexcept;

  /// Current coefficients [C1, C2, C3, C4] in the paper's units (rpm, °C).
  [[nodiscard]] std::array<double, 4> coefficients() const noexcept;
  /// Load persisted coefficients (also becomes the reset point). Rejects non-finite values (returns false).
  bool import_coefficients(const std::array<double, 4>& c) noexcept;

  /// Load a persisted idle correction (after import_coefficients, which clears it). It then counts as
  /// `kIdlePriorObservations` observations, so new idle observations refine it instead of replacing it.
  /// Rejects non-finite values or a non-positive speed (returns false).
  bool import_idle_correction(double correction_nm, double idle_rpm) noexcept;
  static constexpr int kIdlePriorObservations = 10;

  /// Local idle correction δ (N m) and the idle speed it was learned at (rpm); 0 / 0 before any idle
  /// observation.
  [[nodiscard]] double idle_correction_nm() const noexcept { return idle_corr_nm_; }
  [[nodiscard]] double idle_speed_rpm() const noexcept { return idle_rpm_; }
  /// Claimed 1σ of a motoring (fuel cut-off) balance against the law: the 68th percentile of the a-priori
  /// motoring residuals once the law is learned (CoverageScale), learned_sd_nm before. Real-time safe.
  [[nodiscard]] double motoring_sd_nm() const noexcept {
    return std::max(cover_.sd > 0.0 ? cover_.sd : params_.learned_sd_nm, ref_sd_nm_);
  }
  /// 1σ of the most certain load reference the law was learned from (N m; 0: none). Its error is shared by
  /// every observation (an accessory prior, a torque sensor's calibration) and does not average out: the
  /// law's claimed 1σ never goes below it.
  [[nodiscard]] double reference_sd_nm() const noexcept { return ref_sd_nm_; }
  /// A persisted reference_sd_nm() (after import_coefficients, which clears it); false if not finite or < 0.
  bool import_reference_sd(double sd_nm) noexcept;
  [[nodiscard]] const CoverageScale& motoring_residual_scale() const noexcept { return cover_; }
  /// Load a persisted residual scale (after import_coefficients, which clears it). Rejects non-finite or
  /// non-positive scales (returns false).
  bool import_motoring_residual_scale(double sd_nm, std::uint32_t n) noexcept;
  /// The imported law (after import_coefficients) was learned from only `n` motoring observations (fewer than
  /// min_observations): health() stays kNotConverged until the count, carried on, reaches min_observations.
  /// False (nothing changed) for a count that already reaches it.
  bool import_partial(std::uint64_t n) noexcept;
  [[nodiscard]] std::uint64_t motoring_observations() const noexcept { return n_motoring_; }
  [[nodiscard]] std::uint64_t idle_observations() const noexcept { return n_idle_; }
  [[nodiscard]] std::uint64_t rejected() const noexcept { return n_rejected_; }
  /// True while the law rests on the prior alone (no motoring observation learned, nothing imported).
  [[nodiscard]] bool is_prior() const noexcept { return !imported_ && n_motoring_ == 0 && n_idle_ == 0; }
  /// True once the law over speed rests on motoring (or imported coefficients): idle observations alone
  /// correct it near idle only, elsewhere it is still the prior.
  [[nodiscard]] bool speed_law_learned() const noexcept { return imported_ || n_motoring_ > 0; }
  /// kValid once `min_observations` motoring observations were learned (or coefficients were imported),
  /// kNotConverged before (the prior is still used), kDisabled when learning is off (fixed law: kValid).
  [[nodiscard]] Health health() const noexcept;

 private:
  /// Innovation gate of observe_motoring (see there); counts the run of same-side rejections.
  bool gate_rejects(double err, double law_var) noexcept;
  FrictionParams params_;
  std::array<double, 4> base_{};   ///< reset point: configured or imported coefficients
  std::array<double, 3> theta_{};  ///< scaled [C1, C2·1000, C3·1e6]
  std::array<double, 9> p_{};      ///< RLS covariance (row-major 3x3)
  double c4_ = 0.0;
  /// e^{C4 t} of the last law_nm() argument C4·t (one exp per oil temperature or C4 change, not per tooth:
  /// the per-tooth friction law at a steady oil temperature). The learner is one thread's, as its callers'
  /// state.
  mutable double oil_exp_arg_ = 0.0, oil_exp_ = 1.0;
  [[nodiscard]] double oil_factor(double oil_temp_c) const noexcept;
  double p4_ = 0.0;  ///< C4 RLS covariance
  bool have_idle_ref_ = false;
  double idle_ref_oil_c_ = 0.0;
  double idle_ref_ln_ = 0.0;
  double idle_corr_nm_ = 0.0;       ///< local idle correction δ (N m)
  double idle_rpm_ = 0.0;           ///< speed of the idle observations (rpm), 0: none yet
  std::uint64_t idle_prior_n_ = 0;  ///< weight (observations) of an imported idle correction
  bool imported_ = false;
  bool partial_ = false;  ///< the imported law has fewer than min_observations behind it (import_partial)
  double level_ = 1.0;    ///< prior level s learned at idle (law = s · coefficients while level_active())
  double level_ratio_ = 0.0;  ///< running mean of T_idle / law_unscaled(n_idle) over the idle observations
  double level_info_ = 0.0;   ///< information (1/σ²) of s, 0: none beyond the prior
  /// The law is still the generic prior (nothing learned over speed, nothing imported) and may be scaled.
  [[nodiscard]] bool level_active() const noexcept {
    return params_.idle_scales_prior && !imported_ && n_motoring_ == 0;
  }
  void update_level(double speed_rpm, double oil_temp_c, double friction_nm, double obs_sd_nm) noexcept;
  CoverageScale cover_;     ///< motoring residual scale (sd 0: none measured)
  double ref_sd_nm_ = 0.0;  ///< smallest 1σ of the references learned from (N m), 0: none
  std::uint64_t n_motoring_ = 0, n_idle_ = 0, n_rejected_ = 0;
  int gated_run_ = 0;        ///< consecutive motoring observations rejected by the gate, all on one side
  double gated_sign_ = 0.0;  ///< side (sign of the error) of that run
};

}  // namespace torqued
