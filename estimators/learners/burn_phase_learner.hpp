#pragma once
// Burn-phasing learner of the in-cycle gas model (docs/angle_estimators.md (7); the diagnosis in (2)-(6)).
//
// The in-cycle Kalman (chauvin_kalman.hpp) takes the gas torque ripple m(θ; c) of a Wiebe burn whose centroid
// is c = burn_delay − spark advance (LoadRls::centroid_deg) as a known input; its estimate E = x̂2 + M follows
// M = m + T*_load, the correction x̂2 pulling it only part of the way to the truth. Where the engine's own
// burn falls later or earlier after the spark than burn_delay says (a constant of the engine: its Wiebe a and
// m, docs/angle_estimators.md (2)), M leads or lags the truth at the firing order and E with it. This
// learner estimates an offset δ added to the centroid, c = burn_delay − advance + δ, from that phase.
//
// Observable. Per complete cycle of K tooth samples (edge angles e_k over 720°, steps Δ_k), the firing-order
// component (h = n_cyl/2 per revolution, ψ_k = h·e_k) of the estimate and of the model inside it:
//   E_h = Σ_k Δ_k E_k e^{−iψ_k},   M_h = Σ_k Δ_k M_k e^{−iψ_k}
// (the Δ_k weights make the sums integrals across the missing-tooth gap). A component A·cos(h(θ − θ0)) has
// arg = −hθ0, so the model's firing-order lag behind the estimate is
//   d = arg(E_h · conj(M_h)) / h   (crank angle, + = the model's torque later than the estimate's).
// d is the quadrature of the Kalman's correction against the model (E − M = x̂2): zero when the speed
// measurement agrees with the model's phase, whatever the correction's in-phase (amplitude) part. Why E, not
// the measured speed's firing-order component: the speed's order is the torque's divided by J·ω²·h² and
// shifted by the inertia's own order-h term (½J'θ̇², large on an I4 at speed), which would need J(θ), the
// load and the speed trend to be removed first; E has all of them removed by the filter's model (CK-3). Its
// one bias, the learned wheel table's residual at the firing orders (a J·ω²·h²·r torque in quadrature),
// is what tooth_learn.spark_column removes (docs/angle_estimators.md (5), (6)): the learner is meant to run
// with it.
//
// Update (an integrator with a bounded step, applied at each used cycle n):
//   δ_{n+1} = clamp(δ_n + clamp(−g·d_n, ±max_step), [min_offset, max_offset]).
// With s = ∂d/∂δ (0.08-0.3 on the bed's tuning engines, docs/angle_estimators.md (4)-(5): M moves with the
// centroid, E follows a part of it) the loop is δ_{n+1} − δ* = (1 − g·s)(δ_n − δ*): a time constant of
// 1/(g·s) used cycles (3-12 cycles at g = 1), slew-limited to max_step per cycle.
// Quality: the mean phase difference d̄ (first-order, time constant quality_cycles used cycles);
// converged when at least min_cycles were used and |d̄| ≤ converged_deg; learning before; not used while off
// or before its first used cycle.
//
// Gates (named, docs/conventions.md habit 13): a cycle is used when every one of its K samples had a valid
// estimate run with the gas model, a fresh MAP and a fresh spark advance (the centroid follows the spark), no
// fuel cut-off in it or the cycle before (the gas model's p3 follow the fuel state a cycle late), and a
// model ripple whose firing-order amplitude is at least min_ripple_nm (its phase is defined). A stale or
// absent MAP or spark, a cut-off, or an unlearned wheel therefore never moves δ.
// Real-time safe: update() and end_cycle() do not allocate, lock or throw; the cos/sin of ψ_k are tabulated
// at construction.
#include <cstdint>
#include <vector>

#include "engine_geometry.hpp"
#include "params.hpp"

namespace torqued {

/// What the offset rests on (BurnPhaseStats::state).
enum class BurnPhaseState : std::uint8_t {
  kNotUsed = 0,    ///< learning off, or no cycle used yet and nothing imported (the offset is 0)
  kLearning = 1,   ///< cycles used, the mean phase difference not yet within converged_deg
  kConverged = 2,  ///< min_cycles used and |mean phase difference| ≤ converged_deg
  kImported = 3,   ///< an imported offset applied (learned state), no cycle of this run used yet
};

/// Counters and quality (never silent).
struct BurnPhaseStats {
  std::uint64_t cycles_used = 0;      ///< cycles that moved the offset
  std::uint64_t cycles_cutoff = 0;    ///< not used: a fuel cut-off in the cycle or the one before
  std::uint64_t cycles_no_map = 0;    ///< not used: MAP stale or absent at some sample
  std::uint64_t cycles_no_spark = 0;  ///< not used: spark advance stale or absent at some sample
  std::uint64_t cycles_no_model = 0;  ///< not used: estimate invalid or without the gas model at some sample
  std::uint64_t cycles_incomplete = 0;    ///< not used: fewer than K samples (lost teeth, sync)
  std::uint64_t cycles_small_ripple = 0;  ///< not used: firing-order ripple below min_ripple_nm
  double last_phase_deg = 0.0;            ///< d of the last used cycle (deg, + = model later)
  double mean_phase_deg = 0.0;            ///< d̄ (deg)
  BurnPhaseState state = BurnPhaseState::kNotUsed;
};

class BurnPhaseLearner {
 public:
  /// Tabulates the firing-order phase of every sample (allocates here only).
  BurnPhaseLearner(const EngineGeometry& engine, const WheelGeometry& wheel, const BurnPhaseParams& params);

  /// Forgets the offset and the counters.
  void reset() noexcept;
  /// This tooth's signals (the chain's EngineSignals; valid = fresh).
  void set_signals(bool map_valid, bool spark_valid, bool fuel_cutoff) noexcept {
    map_ok_ = map_valid;
    spark_ok_ = spark_valid;
    cut_ = fuel_cutoff;
  }
  /// One estimate of the Kalman: its sample index k (ChauvinKalman::estimate_tooth), T̂_ind and the model
  /// inside it (output_model_nm), `valid` = estimate valid and run with the gas model. Real-time safe.
  void update(int tooth, double estimate_nm, double model_nm, bool valid) noexcept;
  /// Cycle boundary: forms d from the cycle's sums and, when the gates pass, moves the offset. Returns
  /// whether the offset changed. Real-time safe.
  bool end_cycle() noexcept;

  /// Learned offset of the burn centroid (deg, + = later).
  [[nodiscard]] double offset_deg() const noexcept { return offset_deg_; }
  [[nodiscard]] const BurnPhaseStats& stats() const noexcept { return stats_; }
  [[nodiscard]] int samples() const noexcept { return samples_; }
  /// Used cycles behind the offset, the imported ones included (persisted with it).
  [[nodiscard]] std::uint64_t cycles_behind() const noexcept { return stats_.cycles_used + imported_cycles_; }
  /// Restores a persisted offset and the used cycles behind it (state kImported until a cycle of this run is
  /// used); false (nothing changed) outside the bounds.
  bool import_state(double offset_deg, double cycles_used) noexcept;

 private:
  void clear_cycle() noexcept;
  [[nodiscard]] BurnPhaseState quality() const noexcept;

  BurnPhaseParams p_;
  int samples_ = 0;
  double order_ = 0.0;               ///< h: firing order per revolution
  std::vector<double> wcos_, wsin_;  ///< Δ_k cos ψ_k, Δ_k sin ψ_k
  double offset_deg_ = 0.0;
  BurnPhaseStats stats_;
  std::uint64_t imported_cycles_ = 0;
  // This cycle's sums and gates.
  double e_re_ = 0.0, e_im_ = 0.0, m_re_ = 0.0, m_im_ = 0.0;
  int count_ = 0;
  bool all_map_ = true, all_spark_ = true, all_model_ = true, any_cut_ = false, prev_cut_ = false;
  bool map_ok_ = false, spark_ok_ = false, cut_ = false;
};

}  // namespace torqued
