#pragma once
// Crankshaft inertia learned from a known load: J = k · J_spec.
//
// The cycle balance of the Energies 2019 paper (EN-6, energy form CF-2 of docs/equations.md §0) over one 720°
// cycle,
//   k · ΔKE_spec / 4π = T_ind − T_fric(ω) − T_load,
// holds the spec sheet's J in ΔKE_spec = Δ(½ J_spec(θ) θ̇²). A wrong J biases everything learned from a
// decelerating cut-off (friction: the error is (k − 1)·J_spec·θ̈, ≈ 2 N m for a 9 % error at −120 rad/s²) and
// the brake torque of every transient. Friction and J cannot be separated inside one cut-off (θ̈ hardly
// varies), but the difference of two consecutive cycles at the same fuelling removes T_ind and almost all of
// T_fric:
//   k · (ΔKE₂ − ΔKE₁)/4π = −(T_load,2 − T_load,1) − (T_fric(ω₂) − T_fric(ω₁)) + (T_ind,2 − T_ind,1),
// with T_ind,2 − T_ind,1 the fuel model's difference (FuelTorque, learned or its prior) for two fully fired
// cycles of nearly the same fuel and MAP (taken as 0, the fuel steps allowed in a pair biased k by +1-2.4 %
// on the unseen bed: less fuel with the load rising), or the difference of the modelled motored torques for
// two cycles in cut-off. What excites it: a dynamometer or an electric machine changing the load (x =
// Δ(J_spec θ̈) of several N m between cycles). Nothing on a vehicle without a load signal does: there k holds
// its persisted value (or 1, the spec sheet).
//
// Estimate: scalar Bayesian least squares, prior k = 1 ± prior_rel_sd, information I = 1/σ₀² + Σ x²/σ²; no
// forgetting (J does not drift). Pairs whose residual exceeds gate_sigma · σ(residual) are rejected (a CAN
// load step seen one frame late, a misfire, a gear shift), so one bad pair cannot move k. Real-time safe.
#include <cstdint>

#include "params.hpp"

namespace torqued {

class InertiaLearner {
 public:
  explicit InertiaLearner(const InertiaParams& params) noexcept : params_(params) { reset(); }

  /// Back to the prior (k = 1), forgetting every pair.
  void reset() noexcept;

  /// One pair of consecutive cycles: `x_nm` = Δ(ΔKE_spec/4π) between them (spec J), `y_nm` = the torque
  /// change that must balance it (see above). Returns true when learned from; false when not excited (|x| <
  /// min_step_nm), rejected as an outlier, non-finite, or learning is off.
  bool observe(double x_nm, double y_nm) noexcept;

  /// k (J = k·J_spec) and its 1σ.
  [[nodiscard]] double scale() const noexcept { return k_; }
  /// The k the balances use: the learned one once its 1σ ≤ apply_max_sd, the spec sheet's (1) before.
  [[nodiscard]] double applied_scale() const noexcept {
    return scale_sd() <= params_.apply_max_sd ? k_ : 1.0;
  }
  [[nodiscard]] double scale_sd() const noexcept;
  /// Information of the estimate (1/σ²) for persistence; import_state() takes it back.
  [[nodiscard]] double information() const noexcept { return info_; }
  /// Load a persisted estimate; rejects a k outside [min_scale, max_scale] or information below the prior's.
  bool import_state(double scale, double information) noexcept;

  [[nodiscard]] std::uint64_t observations() const noexcept { return n_; }
  [[nodiscard]] std::uint64_t rejected() const noexcept { return n_rejected_; }
  /// True while k rests on the spec sheet alone (nothing learned or imported).
  [[nodiscard]] bool is_prior() const noexcept { return n_ == 0 && !imported_; }

 private:
  InertiaParams params_;
  double k_ = 1.0;
  double info_ = 0.0;  ///< 1/σ_k²
  double sxy_ = 0.0;   ///< information-weighted sum: k = sxy_ / info_
  bool imported_ = false;
  std::uint64_t n_ = 0, n_rejected_ = 0;
};

}  // namespace torqued
