#pragma once
// Crank-wheel tooth-error learning (docs/equations.md §4). A per-tooth machining error changes
// the true width of a tooth period by a FIXED FRACTION, so it appears in the measured speed as the same
// relative pattern at every speed and load, repeating every revolution. The engine's own speed ripple does
// not:
//  - the inertia part (θ̇² ∝ 1/J(θ) from the reciprocating masses, ½J'θ̇²) is known: removed by using ½J(θ)θ̇²;
//  - the torque part (gas and load) is a smooth function of the 720° angle whose relative size falls as 1/ω²
//    (ΔE/E with E = ½Jω²); in fuel cut-off it is only the compression/expansion of the motored cylinders.
// Per complete, steady cycle we form z_k = −½(E_k/Ē − 1), E_k = ½J(c_k)(w_k/dt_k)² with nominal w_k (the
// inertia part cancels, the torque part W(θ) enters linearly, a width ratio ρ_p = w_true/w as ½(1 − ρ_p⁻²),
// inverted exactly when the table is formed, not taken for ln ρ_p), remove the linear
// speed trend measured by the two revolution times, and fit the smooth basis [1, step between the two
// revolutions, cos/sin(hα/2) for every cycle harmonic h ≤ H]. The residual, averaged per physical tooth
// (weighted by speed⁴: the ripple falls as 1/ω̄²), is the tooth error above order H/2 per revolution. The
// per-revolution orders r = h/2 ≤ H/2 (even h) sit in the fitted coefficients together with the engine's
// ripple at the same order, and each is identified by what separates the two:
//  - an order that is not a firing order (h not a multiple of n_cyl; on an I4 the once-per-revolution order,
//  i.e.
//    cylinders 1+4 against 2+3) carries engine ripple only through a cylinder imbalance. In fuel cut-off all
//    cylinders are motored alike, so there the coefficient is the wheel alone ("overrun"). Firing cycles
//    would read the imbalance as wheel error: they are used only through the speed law below, and only when
//    no overrun exists;
//  - a firing order carries the gas torque always (motored compression in cut-off). Its ripple share falls as
//    1/ω̄², the wheel's does not: the intercept (x → 0) of a regression on x = 1/ω̄² across cut-off cycles at
//    several speeds ("overrun speeds"), or across firing cycles at several speeds ("speeds") with a third
//    column x·ln x: the ripple is x·A(ω), and A (the order's gas-torque ripple at that load) drifts with the
//    speed (volumetric efficiency, combustion phasing in crank degrees). An x² column let A vary only at low
//    speed; the drift is largest at the top of the range, where the intercept is read: the x² law left
//    (−1.0, +1.3)e-4 at order 2 of the I4 (the quadrature part: 3° of in-cycle lag at 6000 rpm), x·ln x
//    (−1.1, −0.0)e-4, and x·ln x → 0 with x for any A growing slower than a power of ω;
//  - "speeds" compares firing cycles at the SAME load only: the ripple scales with the load, so
//    where the load changes with the speed (a vehicle, the demo) a regression across loads fakes an
//    intercept, and an imbalance would be learned as wheel error. Each load slot (MAP within ±load_slot_frac
//    of the slot's MAP, steady over the cycle) has its own regression; a slot counts when its speeds spread
//    (min_speed_spread_frac); the slots' intercepts are combined by inverse variance (the variance from the
//    cycles' scatter about the 1/ω̄² law) and the order is identified only when that standard error is small
//    against the wheel's higher orders (max_low_order_se_frac): the variance check;
//  - "firing" needs neither a cut-off nor two cycles at one load: every steady firing cycle with a MAP enters
//    one regression of the coefficient on u = (MAP/p_ref)/ω̄² and x = 1/ω̄² (non-firing orders: u only). The
//    cylinder pressures scale with MAP (compression from MAP at IVC, combustion with the charge), the pumping
//    strokes with p_exh − MAP, so the engine's ripple is (b·MAP + c)/ω̄² at any load and speed, the wheel's
//    intercept is not; cycles at a few speeds and loads identify it (the variance check as above). Taken
//    after the overrun laws and before the same-load slots (all cycles in one law instead of a few per slot);
//    its standard error / high-order RMS is reported per order (firing_se_frac) as the convergence measure,
//    quality() says what the table rests on;
//  - an order nothing identifies is held: the imported (persisted) table's value, or zero.
// order_ids() reports per order how it was identified, from how many cycles, and its edge amplitude.
// The table is absolute (nominal widths, measured times), so the decoder may apply it to its output without
// disturbing learning. Real-time safe update(). Each complete cycle costs its fit (O(teeth·H)) and the sums
// it enters; the table (orders, residual per tooth, width ratios) is solved from those sums every
// solve_every_cycles cycles, at the cycle that makes it ready and at fuel cut-off cycles. The residual sum
// is linear in the cycles, Σw·r = Σw·z − B·G·Σw·z, formed at the solve: the per-cycle fit is needed for the
// per-revolution columns only.
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "engine_geometry.hpp"
#include "params.hpp"
#include "samples.hpp"
#include "tooth_preprocessor.hpp"

namespace torqued {

/// How a per-revolution order inside the per-cycle fit was identified.
enum class ToothOrderSource : std::uint8_t {
  kHeld = 0,     ///< nothing identifies it yet: imported table (or zero)
  kOverrun = 1,  ///< non-firing order: mean over fuel cut-off cycles (no combustion, no imbalance)
  kOverrunSpeeds =
      2,        ///< firing order: intercept of the 1/ω̄² regression over cut-off cycles at several speeds
  kSpeeds = 3,  ///< intercept of the 1/ω̄² (+ x·ln x) regression over firing cycles at several speeds
  kFiring = 4,  ///< intercept of the load law over ALL firing cycles (any load, several speeds and loads):
                ///< no fuel cut-off and no two cycles at the same load needed
};
[[nodiscard]] const char* to_string(ToothOrderSource s) noexcept;

/// Identification of one per-revolution order of the wheel error (orders 1 .. fit_harmonics/2).
struct ToothOrderId {
  int order = 0;        ///< per revolution
  bool firing = false;  ///< a firing order of the engine (gas torque ripple always present)
  ToothOrderSource source = ToothOrderSource::kHeld;
  double cycles = 0.0;              ///< cycles behind the value used
  double edge_amplitude_rad = 0.0;  ///< amplitude of this order in the edge-angle table (rad)
  /// Convergence of the firing-cycle load law for this order: standard error of its intercept / RMS of the
  /// learned higher orders (the variance check takes it at ≤ max_low_order_se_frac); < 0: not estimable yet.
  double firing_se_frac = -1.0;
  /// 1σ of each of this order's cos/sin edge-angle coefficients (rad): the standard error of the law the
  /// value comes from (load law, spark law, same-load speed law; an overrun order: the load law's where it
  /// fits), over the order, shrunk by the import's weight as the value is; a held order without an import:
  /// the prior of independent edge errors from the higher orders' RMS; < 0: not estimable.
  double edge_se_rad = -1.0;
  /// A firing order taken from the load law with the spark column (ToothLearnParams::spark_column): false
  /// when the column is off, or too few cycles with a fresh spark advance identify the order with it.
  bool spark = false;
};

/// Variance of the apparent crank acceleration over ω̄² (rad²) the table's standard errors leave: an
/// edge-angle error ε(θ) = a·cos rθ + b·sin rθ makes the observer read θ̈ off by ω̄²·ε''(θ) = −ω̄²·r²·ε(θ), so
/// torque J·ω̄²·r²·ε; with a and b each of 1σ edge_se_rad the time-mean variance of r²·ε is r⁴·se², summed
/// over the firing orders (independent; the errors that look like torque to the in-cycle observers, whose
/// model is the firing ripple). Orders with edge_se_rad < 0 add nothing. Real-time safe.
[[nodiscard]] double wheel_table_accel_var(std::span<const ToothOrderId> ids) noexcept;

/// What the tooth table rests on, worst order first (ToothErrorLearner::quality()).
enum class ToothLearnQuality : std::uint8_t {
  kNone = 0,        ///< not ready: fewer than min_cycles cycles (the observers say kNotConverged)
  kHighOrders = 1,  ///< ready, but some per-revolution order inside the fit is held (imported value or 0)
  kFiring = 2,      ///< every order identified, at least one only by the firing-cycle load law
  kSpeedLaws = 3,   ///< every order identified, from same-load speed laws or overrun, none by the load law
};
[[nodiscard]] const char* to_string(ToothLearnQuality q) noexcept;

struct ToothLearnStats {
  std::uint64_t cycles_used = 0;    ///< cycles accumulated
  std::uint64_t cycles_cutoff = 0;  ///< of which in fuel cut-off
  std::uint64_t cycles_overrun =
      0;  ///< clean cut-off cycles (whole cycle and the previous one cut) used as overrun
  std::uint64_t cycles_rejected = 0;    ///< incomplete (lost/invalid teeth), unsteady or out of speed range
  std::uint64_t tables_distrusted = 0;  ///< imported tables the engine contradicted (discarded, relearned)
  /// Firing cycles of the load law without a fresh spark advance over the whole cycle: they enter the law
  /// without the spark column only (ToothLearnParams::spark_column).
  std::uint64_t cycles_no_spark = 0;
};

/// Imported table against the fresh evidence (ToothErrorLearner::import_check()): RMS over the teeth of the
/// width disagreement above the fit's orders and of its standard error from the cycles' scatter (rad).
struct ToothImportCheck {
  double disagreement_rad = 0.0;
  double se_rad = 0.0;
  double cycles = 0.0;  ///< fresh cycles behind the comparison
};

class ToothErrorLearner {
 public:
  static constexpr int kMaxFitHarmonics = 48;
  static constexpr int kLoadSlots = 8;  ///< load slots of the speed law (the least used one is recycled)

  ToothErrorLearner(const EngineGeometry& engine, const WheelGeometry& wheel, const ToothLearnParams& params);

  void reset() noexcept;
  /// Fuel cut-off flag of the current cycle (counted in stats; learning runs firing and in cut-off).
  void set_fuel_cutoff(bool cutoff) noexcept { cutoff_ = cutoff; }
  /// Intake manifold pressure at the current tooth (Pa; `valid` false when unknown): firing cycles enter the
  /// speed law only in the load slot of their MAP (no MAP: not at all).
  void set_map(double map_pa, bool valid) noexcept {
    map_pa_ = map_pa;
    map_valid_ = valid && map_pa > 0.0 && std::isfinite(map_pa);
  }
  /// Spark advance at the current tooth (deg BTDC; `valid` false when unknown or stale): a firing cycle with
  /// a fresh spark advance at every tooth enters the load law's spark column
  /// (ToothLearnParams::spark_column).
  void set_spark(double spark_deg, bool valid) noexcept {
    spark_deg_ = spark_deg;
    spark_valid_ = valid && std::isfinite(spark_deg);
  }
  /// Real-time safe. Uses s.tooth, s.dt_s, s.t_ns, s.synced; ignores s.width_rad (learns against nominal
  /// widths).
  void update(const ToothSample& s) noexcept;

  /// Table usable: at least min_cycles cycles learned (or imported).
  [[nodiscard]] bool ready() const noexcept;
  /// Every per-revolution order inside the per-cycle fit identified (none held).
  [[nodiscard]] bool low_orders_learned() const noexcept { return low_orders_ok_; }
  /// Per-order identification (orders 1 .. fit_harmonics/2 per revolution).
  [[nodiscard]] std::span<const ToothOrderId> order_ids() const noexcept { return ids_; }
  [[nodiscard]] const ToothLearnStats& stats() const noexcept { return stats_; }
  /// What the table rests on now (the weakest order decides).
  [[nodiscard]] ToothLearnQuality quality() const noexcept;
  [[nodiscard]] int teeth() const noexcept { return table_.teeth; }
  /// Solve the table now from every cycle accumulated so far (update() does it every solve_every_cycles).
  void solve() noexcept;

  /// True width / nominal width of physical tooth p (period ending at tooth p), 1 when not ready.
  [[nodiscard]] double width_ratio(int p) const noexcept;
  /// Corrected width of the period ending at 720° sample k (rad): what ToothSample::width_rad should carry.
  [[nodiscard]] double corrected_width(int k) const noexcept;
  /// Edge-angle corrections δ_p (rad) per physical tooth, δ_0 = 0: true edge angle = nominal + δ_p.
  /// This is the table CrankDecoder::set_tooth_corrections() takes and the daemon persists. out.size() =
  /// teeth().
  void edge_corrections(std::span<double> out_rad) const noexcept;
  /// The imported table was contradicted by the engine (ToothLearnParams::distrust_*): it is discarded and
  /// the table is the fresh one (ready() again once min_cycles fresh cycles are in). Stays set until reset().
  [[nodiscard]] bool import_distrusted() const noexcept { return distrusted_; }
  /// Last comparison of the imported table with the fresh evidence (cycles 0: none yet).
  [[nodiscard]] const ToothImportCheck& import_check() const noexcept { return check_; }
  /// Restore a persisted table (edge corrections, rad) with the weight of `weight_cycles` learned cycles;
  /// learning continues and blends with it. Returns false if the size does not match.
  bool import_table(std::span<const double> edge_rad, int weight_cycles) noexcept;

 private:
  void finish_cycle() noexcept;
  void fit_cycle() noexcept;
  void regress(double omega) noexcept;
  int load_slot() noexcept;
  /// Inverse-variance combination over the load slots of the intercept of columns j0, j0 + 1 (speed law);
  /// returns false when no slot identifies them. Writes the intercepts, the combined variance and cycles.
  bool slot_intercept(std::size_t j0, bool firing, double* v, double* var, double* cycles) const noexcept;
  void recompute() noexcept;
  void form_residual_sums() noexcept;
  void accumulate_import_scatter(double wgt) noexcept;
  void identify_orders(double* low_coef, double hf_rms) noexcept;
  void check_import() noexcept;

  ToothLearnParams params_;
  ToothAngleTable table_;
  int nb_ = 0;                 ///< fit columns 2H + 2
  std::vector<double> basis_;  ///< B[k * nb_ + j] at period centres c_k
  std::vector<double> trend_;  ///< (c_k − 2π)/2π: linear speed trend, removed with the measured rev times
  std::vector<int> col_per_rev_;   ///< 1 where column j is an even cycle harmonic (can hold wheel error)
  std::vector<int> col_firing_;    ///< 1 where column j is a firing harmonic (multiple of n_cyl per cycle)
  std::vector<int> per_rev_cols_;  ///< the columns j ≥ 2 with col_per_rev_[j], ascending
  std::vector<double> pinv_;       ///< G = (BᵀB)⁻¹Bᵀ, [j * K + k]
  // current cycle
  std::vector<double> z_;  ///< z_k of the cycle being collected
  int next_tooth_ = -1;
  int collected_ = 0;
  double cycle_time_s_ = 0.0;
  double first_dt_s_ = 0.0, last_dt_s_ = 0.0;
  bool cutoff_ = false;
  bool cycle_cutoff_ = false;      ///< any tooth of the cycle in cut-off
  bool cycle_all_cutoff_ = false;  ///< every tooth of the cycle in cut-off
  bool prev_all_cutoff_ = false;   ///< the previous complete cycle was all cut-off
  // accumulators
  std::vector<double> resid_sum_;  ///< Σ weighted residual per 720° sample (formed by recompute())
  std::vector<double> resid_sq_;  ///< Σ weight · residual² per 720° sample (scatter for the import check)
  double w2sum_ = 0.0;            ///< Σ weight² (effective cycle count (Σw)²/Σw²)
  std::vector<double> zw_sum_;    ///< Σ wgt·z_k per 720° sample over the cycles
  std::vector<double> cw_sum_;    ///< scratch of the solve: Σ wgt·β_j = G·Σ wgt·z per fit column
  int since_solve_ = 0;           ///< cycles accumulated since the last solve
  bool solved_ready_ = false;     ///< the last solve saw ready()
  std::vector<double> coef_;      ///< scratch: coefficients of the last cycle
  /// Speed-law sums of one load slot (x = (ω_ref/ω̄)², f = x·ln x); per column j at [j]: Σβ, Σxβ, Σfβ, Σβ².
  struct LoadSlot {
    double map_pa = 0.0;                                                  ///< the slot's load (0: free)
    double n = 0.0, sx = 0.0, sxx = 0.0, sf = 0.0, sxf = 0.0, sff = 0.0;  ///< f = x·ln x
  };
  std::array<LoadSlot, kLoadSlots> slots_{};
  std::vector<double> sb_, sxb_, sfb_, sbb_;  ///< [slot * nb_ + j]
  /// Load law over every steady firing cycle: the slot sums with x replaced by u = (MAP/p_ref)·x and f by x
  /// (β = a + b·u + c·x: the engine's ripple (b·MAP + c)/ω̄², the wheel's a neither).
  LoadSlot fire_{};
  std::vector<double> fb_, fxb_, ffb_, fbb_;  ///< [j]
  /// Intercept of columns j0, j0 + 1 of one regression (slot sums sl; column sums at off); false when the
  /// slot cannot identify them. Writes the intercepts and their variance.
  bool law_intercept(const LoadSlot& sl, const double* sb, const double* sxb, const double* sfb,
                     const double* sbb, std::size_t j0, bool firing, double* v, double* var) const noexcept;
  /// The load law with a spark column, over the firing cycles with a fresh spark advance: β = a + b·u + c·x
  /// + d·u·(spark − spark_ref) (the combustion's phase turns with the spark, so its firing-order components
  /// rotate: linearised, a column per cos/sin coefficient proportional to the load and the spark's change).
  /// Moments of the columns [1, u, x, s] (sm_[r * 4 + c]); per fit column j: Σβ·col at [j * 4 + c], Σβ².
  std::array<double, 16> sm_{};
  std::vector<double> smb_, smbb_;
  /// Intercept of columns j0, j0 + 1 of the spark law, and its variance; false when it cannot identify them.
  bool spark_law_intercept(std::size_t j0, double* v, double* var) const noexcept;
  double spark_deg_ = 0.0;
  bool spark_valid_ = false;
  double cycle_spark_sum_ = 0.0;
  bool cycle_spark_valid_ = false;
  double map_pa_ = 0.0;
  bool map_valid_ = false;
  double cycle_map_sum_ = 0.0, cycle_map_min_ = 0.0, cycle_map_max_ = 0.0;
  bool cycle_map_valid_ = false;
  double n_ = 0.0;
  double wsum_ = 0.0;                       ///< Σ weights of the residuals
  double nc_ = 0.0, cx_ = 0.0, cxx_ = 0.0;  ///< clean overrun cycles, Σx, Σx²
  std::vector<double> cb_, cxb_;            ///< per column over overrun cycles: Σβ, Σxβ
  std::vector<double> low_coef_;   ///< identified wheel coefficient per column (scratch of recompute)
  std::vector<double> imp_coef_;   ///< imported table projected on the per-rev columns
  std::vector<ToothOrderId> ids_;  ///< per order (index order − 1)
  // result
  std::vector<double> eps_;  ///< wheel part of z per physical tooth, ½(1 − ρ⁻²) for the width ratio ρ
  std::vector<double> eps_import_;  ///< imported prior, in the same (z) domain
  double import_weight_ = 0.0;
  bool distrusted_ = false;
  ToothImportCheck check_{};
  std::vector<double> ratio_;  ///< (1 − 2·eps)^−½ normalised so that Σ ratio·w = 2π
  bool low_orders_ok_ = false;
  ToothLearnStats stats_;
};

}  // namespace torqued
