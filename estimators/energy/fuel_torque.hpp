#pragma once
// Fuel-based indicated torque whose efficiency extrapolates over the speed × load map (docs/equations.md §5;
// docs/angle_pipeline.md "Fuel model"). The vehicle has no load-torque signal, but the ECU reports the
// injected fuel mass (and usually MAP, spark advance and λ) on CAN. Energies 2019 EN-16/EN-17 with the
// pumping loop (Heywood 1988 ch. 5, 13):
//   W_ind = m_f q_LHV · Eff,  Eff = (1 − r_c^{1−κ}) · min(1, λ) · η_ign(θ_ign) · η_ig,ch(ω, load)  (EN-16,
//   17) T_ind = n_cyl W_ind / 4π − (p_exh − p_man) V_d / 4π
// with
//   η_ign  = 1 − k_sp (θ_ign − θ_MBT(ω, p_man))²            (spark on CAN, else 1; θ_MBT a textbook line)
//   η_ig,ch = c0 − c1 · h,  h = (ω_ref/ω)^a (p_ref/p_man)^b (heat loss grows at low speed and low load:
//                                                           Woschni scaling, Heywood §12.4)
//   p_exh  = p_amb + p_off + k_bp · x²,  x = (ω/ω_rated)(p_man/p_ref) (back-pressure grows with mass flow)
// Four parameters θ = [c0, c1, p_off, k_bp] are learned, each with a physical prior (mean, 1σ) from the
// schema; none comes from a simulated engine. The model is linear in θ:
//   y = T_ind,ref + (p_amb − p_man) V_d/4π = G·c0 − G h·c1 − (V_d/4π)·p_off − x² (V_d/4π)·k_bp
// (G = η_otto η_ign η_λ n_cyl m_f q_LHV / 4π), so a Bayesian RLS started at the prior learns it: what one
// operating point cannot identify stays at its prior (the prior regularises), 2-3 points fix the map. The
// covariance never grows beyond the prior's (forgetting only forgets information, never the prior), and the
// claimed 1σ is the parameter uncertainty at the operating point plus a residual scale: before references
// a model-form share of the gross work (the prior's own error), once learned the 68th percentile of
// |reference residual| (CoverageScale). References beyond the 5σ gate are outliers, unless gate_reaccept of
// them in a row fall on one side: then what was learned is wrong and its covariance restarts. Transient
// references count, with the window's spread as extra measurement noise (FuelAngleWindow aligns fuel and work
// per intake event). A 4 × 4 speed × MAP grid counts the references per cell (DaemonStatus, metrics).
// Real-time safe: no allocation, no exceptions.
#include <array>
#include <cstdint>

#include "coverage_scale.hpp"
#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "fuel_angle_window.hpp"

namespace torqued {

inline constexpr int kFuelParams = 4;      ///< θ = [c0, c1, p_off (Pa), k_bp (Pa)]
inline constexpr int kFuelCellsSpeed = 4;  ///< grid of learned cells: speed bands
inline constexpr int kFuelCellsMap = 4;    ///< ... × MAP bands
inline constexpr int kFuelCells = kFuelCellsSpeed * kFuelCellsMap;

struct FuelTorqueParams {
  // Priors (mean, 1σ) of the learned parameters: physics and published orders of magnitude only.
  double c0_prior = 0.93;          ///< η_ig,ch without heat loss: combustion and finite-burn losses (-)
  double c0_prior_sd = 0.0425;     ///< its 1σ (-)
  double c1_prior = 0.08;          ///< heat-loss share of the ideal work at the reference speed and MAP (-)
  double c1_prior_sd = 0.0425;     ///< its 1σ (-)
  double p_off_prior_pa = 3000.0;  ///< exhaust pressure above ambient at no flow (Pa); its 1σ also holds the
                                   ///< unknown ambient (altitude: −10 kPa at 900 m)
  double p_off_prior_sd_pa = 4250.0;  ///< its 1σ (Pa)
  double k_bp_prior_pa = 30000.0;     ///< back-pressure at the rated flow (Pa): catalyst + silencer
  double k_bp_prior_sd_pa = 17000.0;  ///< its 1σ (Pa)
  double range_sd =
      10.0;  ///< each learned parameter stays within its prior ± this many 1σ (-): a guard against
             ///< run-away; the constant pumping term also absorbs the references' constant offsets
  // Fixed physics of the model.
  double kappa = 1.3;  ///< κ of the Otto efficiency 1 − r_c^{1−κ} (burned-gas order, Heywood §5.3)
  double ambient_pa = 101325.0;  ///< ambient pressure (Pa)
  double ref_rpm = 2000.0;       ///< reference speed of the heat-loss term (rpm)
  double ref_map_pa = 100000.0;  ///< reference MAP of the heat-loss and flow terms (Pa)
  double heat_speed_exp = 0.2;   ///< a in h = (ω_ref/ω)^a (p_ref/p_man)^b (Woschni: h_c ∝ p^0.8 w^0.8)
  double heat_load_exp = 0.2;    ///< b
  double rated_rpm = 6000.0;     ///< speed of the rated exhaust flow (rpm)
  double spark_k_per_deg2 =
      3e-4;  ///< k_sp of η_ign = 1 − k_sp Δθ² (≈ 0.88 at 20° from MBT, Heywood fig. 15-13)
  double mbt_deg = 25.0;          ///< θ_MBT at ref_rpm and ref_map (deg BTDC)
  double mbt_per_krpm_deg = 3.0;  ///< θ_MBT slope with speed (deg per 1000 rpm): longer burn angle
  double mbt_per_vacuum_deg =
      10.0;  ///< θ_MBT added at zero MAP (deg, linear in 1 − p_man/p_ref): slower burn
  double model_rel_sd =
      0.0255;  ///< model-form 1σ: share of the gross indicated torque (-); the five prior 1σ
               ///< above and this one are scaled together so that the never-taught model's
               ///< 1σ covers 68 % on 12 simulated calibration engines (torque-accuracy --bed-priors)
  double model_rel_sd_learned =
      0.0075;  ///< the same in a speed × MAP cell with references (-); TUNING engines
  // Learning.
  double forgetting = 0.999;    ///< RLS forgetting per reference cycle; the covariance stays ≤ the prior's
  double residual_sd_nm = 2.0;  ///< measurement 1σ of one reference cycle (N m)
  int min_references = 30;      ///< references before the residual scale is measured ("learned") (-)
  int cell_min_references = 5;  ///< references in a speed × MAP cell before it counts as learned (-)
  int gate_reaccept = 10;  ///< once learned, so many references in a row beyond the 5σ gate on the same side
                           ///< mean the model is wrong: its covariance and residual scale restart (-)
  double sd_ema = 0.005;   ///< residual variance: EMA weight before learned, floor of the running-mean weight
                           ///< 1/k after (-)
  double fuel_lhv_j_kg = 43e6;  ///< q_LHV (J/kg)
  // The angle window (FuelAngleWindow): which intake events' fuel and MAP a 720° window's work comes from.
  double intake_btdc_deg = 130.0;  ///< intake event (IVC, fuel decided) before firing TDC (deg): IVC 40-60°
                                   ///< after BDC (Heywood 1988 §6.3)
  double work_centroid_atdc_deg = 160.0;  ///< centroid of a cylinder's work after its firing TDC (deg);
                                          ///< chosen on the unseen bed's TUNING engines only
  double report_window_s =
      0.010;  ///< an intake event's cut-off state is revised by consistent CAN reports for this
              ///< long after it (s): one period of a 100 Hz ECU frame (the CAN frame seen at
              ///< the intake can be that much older than the injection decision)
  double transient_sd_scale =
      0.25;                  ///< claimed 1σ added per N m of model-torque spread across the window (-)
  double sd_floor_nm = 0.1;  ///< the coverage-calibrated residual scale never claims less (N m)
  /// 1σ of the bias the driveline-open references share (N m): AnglePipeline sets it from
  /// can.load_reference.accessory_sd_nm (the accessories' prior), not a tunable of its own.
  double shared_bias_sd_nm = 2.0;
};

/// Operating point of one fuel-model evaluation (CAN values at the window's intake events, cycle speed).
struct FuelPoint {
  double fuel_kg = 0.0;    ///< fuel per injection per cylinder (kg)
  double map_pa = 0.0;     ///< manifold pressure (Pa)
  double rpm = 2000.0;     ///< mean speed of the cycle (rpm)
  double spark_deg = 0.0;  ///< spark advance (deg BTDC), when `spark_valid`
  double lambda = 1.0;     ///< air/fuel equivalence λ, when `lambda_valid`
  bool spark_valid = false;
  bool lambda_valid = false;
};

/// Learned state (persisted with the friction coefficients: state file line fuel_model).
struct FuelTorqueState {
  std::array<double, kFuelParams> theta{};            ///< [c0, c1, p_off Pa, k_bp Pa]
  std::array<double, kFuelParams * kFuelParams> p{};  ///< RLS covariance (row-major)
  /// Cross-covariance of θ with the one bias the driveline-open references share (the accessories' prior:
  /// the same error in every such reference, which no count of them averages out), units of θ × N m. A
  /// Schmidt "consider" term: the bias is not estimated, only carried (FuelTorque::learn).
  std::array<double, kFuelParams> pxb{};
  double resid_var = 0.0;  ///< residual variance (N m²): the outlier gate's scale
  std::uint32_t references = 0;
  CoverageScale cover;  ///< 68th percentile of |residual| once learned (N m), sd 0: not yet
  std::array<std::uint16_t, kFuelCells> cells{};  ///< references per speed × MAP cell (saturating)
  // The two-parameter (Willans) view at the reference point, kept current by FuelTorque: the legacy fields
  // of the state file's fuel_model line, which older files carry alone.
  double eta_ref = 0.0;        ///< gross indicated efficiency at ref_rpm / ref_map (-)
  double p_exh_nm = 0.0;       ///< p_exh V_d / 4π there (N m)
  std::array<double, 4> p2{};  ///< their covariance (row-major 2 × 2)
  bool physics = true;         ///< false: only the legacy view is known (an older file)
};
/// FuelTorqueState as a flat array of doubles (lock-free snapshots).
inline constexpr int kFuelStateDoubles = 2 * kFuelParams + kFuelParams * kFuelParams + 4 + kFuelCells + 7;
void pack(const FuelTorqueState& s, std::array<double, kFuelStateDoubles>& v) noexcept;
[[nodiscard]] FuelTorqueState unpack(const std::array<double, kFuelStateDoubles>& v) noexcept;

class FuelTorque {
 public:
  FuelTorque(const EngineGeometry& engine, const FuelTorqueParams& params) noexcept;
  void reset() noexcept;
  /// Indicated torque (N m) at an operating point; health kValid whenever the inputs are finite (the prior
  /// model with its wide 1σ before any reference: prior_only()).
  [[nodiscard]] TorqueEstimate estimate(std::int64_t t_ns, const FuelPoint& x) const noexcept;
  /// Same at the reference speed without spark and λ (tests, the inertia learner's differences).
  [[nodiscard]] TorqueEstimate estimate(std::int64_t t_ns, double fuel_kg, double map_pa,
                                        double rpm = 2000.0) const noexcept;
  /// Indicated torque of a 720° window (FuelAngleWindow): its fired events by the fuel model at `x`'s speed,
  /// spark and λ, its cut-off events by `motored` (no combustion; the fuel model at zero fuel when `motored`
  /// is not valid), weighted by their count. The claimed 1σ grows with the spread of the model torque across
  /// the window's events (transients, cut-off entry/exit).
  [[nodiscard]] TorqueEstimate estimate_window(std::int64_t t_ns, const FuelWindow& w, const FuelPoint& x,
                                               const TorqueEstimate& motored) const noexcept;
  /// The window's transient 1σ share (N m): transient_sd_scale × the spread of one event's model torque
  /// across the window's events (fuel, MAP, a cut-off edge) / events.
  [[nodiscard]] double transient_sd_nm(const FuelWindow& w, const FuelPoint& x) const noexcept;
  /// One reference: true indicated torque `t_ind_ref` (N m) at `x`; `extra_sd_nm` is the reference's own
  /// extra noise (a transient window's spread); `shared_bias`: the reference rests on the accessories' prior
  /// (driveline open, no measured load), whose error (1σ shared_bias_sd_nm) is the same in every such
  /// reference: a Schmidt-Kalman consider parameter (Simon 2006, §7.5), so that many of them at one operating
  /// point (idle) do not claim to fix the map. Rejects non-finite input and residuals beyond 5σ (residual,
  /// parameter and shared-bias uncertainty) once learned. Returns true when learned from.
  bool learn(const FuelPoint& x, double t_ind_ref, double extra_sd_nm = 0.0,
             bool shared_bias = false) noexcept;
  bool learn(double fuel_kg, double map_pa, double t_ind_ref) noexcept;
  [[nodiscard]] const FuelTorqueState& state() const noexcept { return st_; }
  /// A saved state; one with only the legacy two-parameter view (physics false) is converted (from_willans).
  bool import_state(const FuelTorqueState& s) noexcept;
  /// The state the prior gives (no reference).
  [[nodiscard]] FuelTorqueState prior_state() const noexcept;
  /// An older two-parameter state (η at the reference point, p_exh V_d/4π N m, its 2 × 2 covariance) as
  /// the model's state: c0 from η, p_off from p_exh; c1 and k_bp at their priors.
  [[nodiscard]] FuelTorqueState from_willans(double eta, double p_exh_nm, const std::array<double, 4>& p2,
                                             double resid_var, std::uint32_t references) const noexcept;
  /// Times gate_reaccept gated references in a row restarted the learning (since construction).
  [[nodiscard]] std::uint32_t relearns() const noexcept { return relearns_; }
  /// Residual scale measured: enough references for a claimed σ of its own.
  [[nodiscard]] bool valid() const noexcept {
    return st_.references >= static_cast<std::uint32_t>(params_.min_references);
  }
  [[nodiscard]] bool prior_only() const noexcept { return st_.references == 0; }
  /// Bit i: speed × MAP cell i (speed band i / 4, MAP band i % 4) has ≥ cell_min_references.
  [[nodiscard]] std::uint16_t learned_cells() const noexcept;
  /// Cell of an operating point (speed bands < 1500, < 2500, < 3500, ≥ 3500 rpm; MAP < 40, < 60, < 80, ≥ 80
  /// kPa).
  [[nodiscard]] static int cell_of(double rpm, double map_pa) noexcept;

 private:
  struct Regressor {
    std::array<double, kFuelParams> phi{};
    double offset = 0.0;    ///< T_ind = φ·θ − offset
    double gross_nm = 0.0;  ///< prior model's gross indicated torque (model-form σ)
  };
  [[nodiscard]] Regressor regressor(const FuelPoint& x) const noexcept;
  [[nodiscard]] double param_var(const Regressor& r) const noexcept;
  [[nodiscard]] double residual_var(const Regressor& r) const noexcept;
  void cap_covariance() noexcept;
  bool update(const std::array<double, kFuelParams>& phi, double err, double r, double vb,
              double phi_pxb) noexcept;
  void count_reference(const FuelPoint& x, double err, double sp) noexcept;
  void bound_shared_bias() noexcept;
  void refresh_legacy() noexcept;
  void observe_coverage(double err) noexcept;
  /// Counts a gated reference; true when gate_reaccept of them in a row fell on the same side.
  bool gated_run(double err) noexcept;
  void relearn() noexcept;
  FuelTorqueParams params_;
  int n_cyl_;
  double vd_4pi_;  ///< V_d / 4π (m³/rad)
  double eta_otto_;
  std::array<double, kFuelParams> prior_sd_{};
  FuelTorqueState st_;
  int gated_ = 0;       ///< gated references in a row (same side)
  int gated_sign_ = 0;  ///< their side
  std::uint32_t relearns_ = 0;
};

}  // namespace torqued
