#pragma once
// Adaptive time-varying parameter estimator of the effective torque, Na et al. 2017 eq. (41)-(54).
//   τ_e = φᵀθ(t), φ = [ω·s0, ṁ_air·s1] (normalised, AdaptiveParams::phi_scale)            (Na-41)
//   k φ̇_f = −φ_f + φ; ω_f, τ_lf as the UIO; y_f = J(ω − ω_f)/k + τ_lf ≈ φ_fᵀθ          (Na-42/44)
//   Ṗ = −ℓP + φ_fφ_fᵀ, Q̇ = −ℓQ + φ_f y_f, P(0) = 0, Q(0) = 0                             (Na-45)
//   W1 = Pθ̂ − Q, W2 = φ_f(φ_fᵀθ̂ − y_f)                                                  (Na-46/47)
//   law (50): θ̂̇ = −Γ(W1 + κW2);  law (54): θ̂̇ = −ΓK(W1 + κW2), K̇ = ℓK − Kφ_fφ_fᵀK      (Na-50/52/54)
//   τ̂_e = φᵀθ̂; excitation level λ_min(P), "not excited" below σ (Na Remark 9, Lemma 8).
//
// Discretisation (inputs held over the step T, ZOH):
// - φ_f, ω_f, τ_lf: exact ZOH low-pass (first_order_filter.hpp), 1/k → α/T as in the UIO.
// - P, Q: linear with constant coefficients over a step, so exactly
//     P[n+1] = e^{−ℓT} P[n] + (1 − e^{−ℓT})/ℓ · φ_fφ_fᵀ   (same for Q with φ_f y_f).
// - K: the Riccati equation (52) is linear in M = K⁻¹: Ṁ = −ℓM + φ_fφ_fᵀ (Na-53), so M is propagated
//   exactly like P and K = M⁻¹ is the closed-form 2×2 inverse. Deviation from the paper: M is kept above
//   k0_floor·K0 (Ṁ gets + ℓ·k0_floor·K0), otherwise K grows like e^{ℓt} in any direction that stops being
//   excited (steady operation makes [ω, ṁ] collinear) — the classic covariance wind-up.
// - θ̂: linear in θ̂ but stiff (rates Γ·λ(P + κφ_fφ_fᵀ) reach 10²–10⁴ /s with the 1 ms step, and the 2×2
//   matrix exponential of a non-symmetric ΓK(P+κφφᵀ) costs more than the budget), so backward Euler:
//     (I + T·G·S) θ̂[n+1] = θ̂[n] + T·G·b,  S = P + κφ_fφ_fᵀ, b = Q + κφ_f y_f, G = Γ or ΓK.
//   It is A-stable and L-stable (fast directions settle in one step instead of diverging), and first-order
//   accurate in the slow directions; the error against a fine-step integration is tested.
#include <Eigen/Core>

#include "estimate.hpp"
#include "first_order_filter.hpp"
#include "params.hpp"
#include "time_sample.hpp"

namespace torqued {

class AdaptiveTv {
 public:
  static constexpr int kN = 2;  ///< regressor dimension [speed, air mass flow]
  using Vec = Eigen::Matrix<double, kN, 1>;
  using Mat = Eigen::Matrix<double, kN, kN>;

  AdaptiveTv(const AdaptiveParams& params, double inertia_kgm2, double step_s = 0.001) noexcept;

  void reset() noexcept;
  /// One step; needs speed, load and air mass flow. Stale/invalid input holds θ̂ and the estimate. Real-time
  /// safe.
  void update(const TimeSample& s) noexcept;
  /// torque_nm = φᵀθ̂, uncertainty = λ_min(P) (excitation level), health kNotExcited while λ_min(P) < σ.
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return estimate_; }

  [[nodiscard]] const Vec& theta() const noexcept { return theta_; }  ///< θ̂ in normalised units (N m)
  /// θ̂ in SI: [N m s/rad, N m s/kg] so that τ̂_e = θ_si·[ω, ṁ_air].
  [[nodiscard]] Vec theta_si() const noexcept;
  [[nodiscard]] double lambda_min_p() const noexcept { return lambda_min_p_; }
  [[nodiscard]] const Mat& p() const noexcept { return p_; }
  [[nodiscard]] const Vec& q() const noexcept { return q_; }
  [[nodiscard]] const Mat& gain_k() const noexcept { return k_; }
  [[nodiscard]] const Mat& gain_k_inverse() const noexcept { return m_; }
  [[nodiscard]] double filtered_torque_nm() const noexcept { return y_f_; }  ///< y_f (Na-44)

  /// Smallest eigenvalue of a symmetric 2×2 matrix (closed form).
  [[nodiscard]] static double lambda_min(const Mat& a) noexcept;

 private:
  void fail_numerical(std::int64_t t_ns) noexcept;
  void set_step(double step_s) noexcept;

  AdaptiveParams params_;
  double inertia_kgm2_;
  Mat gamma_;  ///< Γ of the selected law
  Mat k0_;     ///< K(0)^-1 = K0
  Vec scale_;  ///< φ normalisation
  double step_s_ = -1.0;
  double decay_ = 1.0;  ///< e^{−ℓT}
  double beta_ = 0.0;   ///< (1 − e^{−ℓT})/ℓ
  FirstOrderFilter<double> omega_f_;
  FirstOrderFilter<double> load_f_;
  FirstOrderFilter<Vec> phi_f_;
  Mat p_ = Mat::Zero();
  Vec q_ = Vec::Zero();
  Mat m_ = Mat::Identity();  ///< K^-1
  Mat k_ = Mat::Identity();  ///< K
  Vec theta_ = Vec::Zero();
  double y_f_ = 0.0;
  double lambda_min_p_ = 0.0;
  bool primed_ = false;
  double running_s_ = 0.0;
  TorqueEstimate estimate_{};
};

}  // namespace torqued
