#pragma once
// Chauvin's time-varying Kalman filter for the combustion (indicated) torque in the angle domain
// (Chauvin et al., "Real-time combustion torque estimation ... using time-varying Kalman filtering", eqs.
// (3)-(13), coloured-noise model (18)); docs/equations.md §2.1.
//
// State (one sample per tooth period, index k in the 720° cycle, see ToothAngleTable):
//   x = [θ̇²(k), x2(k), x2(k−1), …, x2(k−kMaxLag)],  x2 = T_ind − T*_load (net torque, N m).
// Model, from the energy balance d(½Jθ̇²)/dθ = x2 + m_k (CF-2) integrated over Δ_k (midpoint e_k):
//   x1(k+1) = J(c_k)/J(c_{k+1}) · x1(k) + 2Δ_k/J(c_{k+1}) · (x2(k) + m_k)
// which is (CK-3) [1 − 2Δα f̄/J ≈ J_k/J_{k+1}] without its first-order truncation and with exact unequal steps
// across the gap. m_k is a known input (beyond the paper): the zero-mean gas torque ripple of a
// cylinder-pressure model over the step (set_model_torque; 0 without one), so x2 = T_ind − T*_load − m and
// T̂_ind = x2 + m + T*_load. Coloured noise (CK-18): x2(k+1) = 2a x2(k) − a² x2(k−1) + (1−a)² u(k), a =
// e^{−δΔ_k}, δ = delta (the paper's filter) or model_delta (while the gas model is valid). The extra lags
// (beyond the paper's q = 2) make a fixed-lag smoother: the filtered estimate of x2(k−d) uses d more teeth of
// speed and removes most of the predictor's phase lag (d = smoother_lag ≤ kMaxLag = 12, latency d teeth; at
// 6000 rpm the filter's memory outgrows 6 teeth). Measurement y_k = θ̇²(k) = (w_k/dt_k)², R_k from the
// edge-angle error and jitter (relative, so R ∝ θ̇⁴). Because R depends on speed, the asymptotic periodic
// gains (APS, CK §VI and Bittanti Theorem 3) are computed at start-up for a log-spaced set of speeds and
// interpolated; the exact-Riccati variant (11)-(13) runs P on line. Measurement noise (beyond the paper): an
// edge-angle error or timestamp error e_k (equivalent angle, rad) of edge k shortens period k and lengthens
// period k+1, so y_k = θ̇²(c_k) + (2θ̇²/w_k)(e_{k−1} − e_k): moving-average noise whose power at the low orders
// that carry the torque is a small fraction of the white R the paper assumes (for order o of a K-sample
// cycle, 2(1 − cos 2πo/K) instead of 2). With differenced_edge_noise the two edge errors are states, v = 2θ̇²e
// ((rad/s)² rad, fresh each tooth with variance 4θ̇⁴σ_e², and its copy), y_k = x1 + (v_{k−1} − v_k)/w_k, and R
// keeps only a small floor (Bryson & Henrikson's state augmentation for coloured measurement noise). In these
// units the gains of the edge states scale with speed like those of x1, so the APS interpolation between
// speed bins stays as accurate.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "lag_ring.hpp"
#include "params.hpp"
#include "samples.hpp"
#include "tooth_preprocessor.hpp"

namespace torqued {

/// Counters (never silent).
struct KalmanStats {
  std::uint64_t updates = 0;
  std::uint64_t rejected = 0;       ///< not synced / invalid sample
  std::uint64_t skipped_teeth = 0;  ///< tooth index jumps bridged by prediction
  std::uint64_t resets = 0;         ///< numerical resets (non-finite state or covariance)
};

class ChauvinKalman {
 public:
  static constexpr int kMaxLag = 12;
  // Named state indices (typed indices as in PX4 EKF2's state layout), x = [θ̇², x2(k), x2(k−1), …,
  // x2(k−kMaxLag), v_k, v_{k−1}]; the covariance P uses the same indices.
  static constexpr int kSpeedSqState = 0;                 ///< θ̇²(k) ((rad/s)²), the measured state
  static constexpr int kTorqueState = 1;                  ///< x2(k) = net torque (N m), newest
  static constexpr int kTorquePrevState = 2;              ///< x2(k−1) (N m), start of the lag register
  static constexpr int kTorqueLastState = 1 + kMaxLag;    ///< x2(k−kMaxLag) (N m), end of the lag register
  static constexpr int kNoiseNow = kTorqueLastState + 1;  ///< state index of v_k = 2θ̇²e_k (edge k's error)
  static constexpr int kNoisePrev = kTorqueLastState + 2;  ///< state index of v_{k−1}
  static constexpr int kStates = kTorqueLastState + 3;
  static_assert(kNoiseNow == 2 + kMaxLag && kNoisePrev == 3 + kMaxLag && kStates == 4 + kMaxLag);
  /// Noise sets (index of qu_, sd_ and the APS gain sets): the whole net torque, or the gas model's miss.
  static constexpr int kWholeTorqueSet = 0;
  static constexpr int kModelMissSet = 1;
  using Vec = Eigen::Matrix<double, kStates, 1>;
  using Mat = Eigen::Matrix<double, kStates, kStates>;

  /// Builds the per-tooth model and (periodic_gains) the APS gain tables. Allocates here only.
  ChauvinKalman(const EngineGeometry& engine, const WheelGeometry& wheel, const KalmanParams& params);

  void reset() noexcept;
  /// Extended load T*_load = T_load + T_fric (N m), added to x̂2 to give T̂_ind (CK eq. (1)). Default 0.
  void set_extended_load(double torque_nm) noexcept { load_star_nm_ = torque_nm; }
  /// Known part of the net torque over the coming step [c_k, c_{k+1}] of the next update()'s tooth k (N m,
  /// zero 720° mean): the gas torque ripple of a cylinder-pressure model (LoadRls::gas_ripple_nm).
  /// The state x2 then carries only what the model misses, which the coloured-noise prior (CK-18) fits far
  /// better than the sharp compression/expansion waveform itself: the smoothing that R forces at high speed
  /// (jitter ∝ θ̇³) acts on the model's error instead of on the torque. Default 0 (the paper's zero-mean
  /// prior).
  /// `valid` false (no model: no MAP yet) ignores the value and runs the filter with the whole net torque's σ
  /// (torque_sd_nm) instead of the model miss's (model_torque_sd_nm): two APS gain sets, chosen per tooth.
  void set_model_torque(double ripple_nm, bool valid = true) noexcept {
    model_next_ = ripple_nm;
    model_next_valid_ = valid;
  }
  /// Whether the last update ran with the gas model (model_torque_sd_nm) (diagnostics, tests).
  [[nodiscard]] bool model_active() const noexcept { return mode_ == kModelMissSet; }
  /// Whether the tooth widths it is given are corrected by a learned table. While false the
  /// estimate runs but its health is kNotConverged: an unlearned wheel puts the tooth errors into the
  /// in-cycle torque (tens of % of peak-to-peak). Default true (a caller without a learner decides).
  void set_wheel_learned(bool learned) noexcept { wheel_learned_ = learned; }
  /// Real-time safe (no allocation, no exception). Returns false if the sample was rejected.
  bool update(const ToothSample& s) noexcept;
  /// update() for a sample that passed check_tooth_sample for this table (AnglePipeline::on_tooth checks once
  /// per tooth). Real-time safe.
  bool update_checked(const ToothSample& s) noexcept;

  /// Indicated torque T̂_ind at the edge `estimate_tooth()` (t_ns of that edge), 1σ from P.
  [[nodiscard]] const TorqueEstimate& estimate() const noexcept { return est_; }
  [[nodiscard]] int estimate_tooth() const noexcept { return est_tooth_; }
  [[nodiscard]] double net_torque_nm() const noexcept { return est_.torque_nm - load_star_nm_; }
  [[nodiscard]] const Vec& state() const noexcept { return x_; }
  [[nodiscard]] const KalmanStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const ToothAngleTable& table() const noexcept { return table_; }

  /// Filter gain K_k = P Cᵀ/(C P Cᵀ + R) last applied (for the APS vs exact test).
  [[nodiscard]] const Vec& last_gain() const noexcept { return last_gain_; }
  /// Innovation y − C x̂_{k|k−1} of the last update ((rad/s)²; diagnostics: torque-accuracy's per-tooth dump).
  [[nodiscard]] double last_innovation() const noexcept { return last_innovation_; }
  /// The gas model's ripple and the extended load inside the last estimate() (N m; T̂_ind = x̂2(k−d) + both).
  [[nodiscard]] double output_model_nm() const noexcept { return output_model_nm_; }
  [[nodiscard]] double extended_load_nm() const noexcept { return load_star_nm_; }
  /// APS filter gain at tooth k for speed ω (interpolated between the precomputed speed bins).
  [[nodiscard]] Vec periodic_gain(int k, double speed_rad_s) const noexcept;
  /// The same from noise set `set` (kWholeTorqueSet, or kModelMissSet when built with gas_model), whichever
  /// set the last update() used (tests).
  [[nodiscard]] Vec periodic_gain_of_set(int set, int k, double speed_rad_s) const noexcept;
  /// Posterior variance of the output state x2(k−d | k) ((N m)²) at tooth k for speed ω under the APS gains
  /// (the periodic Riccati solution's, interpolated as the gains are): the claimed 1σ² of the estimate.
  [[nodiscard]] double periodic_output_var(int k, double speed_rad_s) const noexcept;
  /// periodic_gain() into `gain` and periodic_output_var() returned, bit for bit, from one speed-bin position
  /// (the per-tooth path: one log ω, no temporary).
  double periodic_gain_var_into(int k, double speed_rad_s, Vec& gain) const noexcept;
  /// One exact Riccati step (CK-12/13) for tooth k at speed ω: returns the filter gain and advances P in
  /// place.
  void riccati_step(int k, double speed_rad_s, Mat& p, Vec& gain) const noexcept;
  /// riccati_step() for a bit-symmetric P (as every P of the APS iteration is), bit for bit the same result,
  /// a third of the work (the sparsity of A_k and the symmetry written out).
  void riccati_step_symmetric(int k, double speed_rad_s, Mat& p, Vec& gain) const noexcept;
  /// White measurement noise variance R_k at speed ω ((rad/s)^4): the whole edge noise, or (differenced) its
  /// floor.
  [[nodiscard]] double measurement_var(int k, double speed_rad_s) const noexcept;
  /// Coupling 1/w_k of the edge-error states into y_k (1/rad); 0 when not differenced.
  [[nodiscard]] double edge_coupling(int k) const noexcept;
  /// Variance of a fresh edge-error state at speed ω, 4θ̇⁴σ_e² (((rad/s)² rad)²); 0 when not differenced.
  [[nodiscard]] double edge_state_var(double speed_rad_s) const noexcept;

 private:
  /// periodic_gain() written into `gain` (the per-tooth path: no temporary).
  void periodic_gain_into(int k, double speed_rad_s, Vec& gain) const noexcept;
  struct BinPos {
    std::size_t lo, hi;  ///< APS table slots of the two speed bins around ω (current noise set, tooth k)
    double t;            ///< interpolation weight of `hi`
  };
  [[nodiscard]] BinPos bin_pos(int k, double speed_rad_s) const noexcept;
  /// bin_pos() from ln ω (ω already clamped to ≥ 1e-3 rad/s).
  [[nodiscard]] BinPos bin_pos_log(int k, double log_speed) const noexcept {
    return bin_pos_log(mode_, k, log_speed);
  }
  [[nodiscard]] BinPos bin_pos_log(int set, int k, double log_speed) const noexcept;
  /// The running mean speed's update and its logarithm for the APS bin (per tooth): ln ω̄ exact at a
  /// (re)start and once per cycle, in between advanced by ln(1 + u), u = Δω̄/ω̄ (a short series).
  void advance_mean_speed(double omega) noexcept;
  void push_edge_time(std::int64_t t_ns) noexcept;
  void push_model(double ripple_nm) noexcept;
  /// Appends gain set `set` to `out` (kStates doubles per slot) and writes its variances into aps_var_.
  void build_aps_set(int set, int bins, std::vector<double>& out);
  void build_aps_tables(int bins);
  [[nodiscard]] std::uint64_t aps_key(int sets, int bins) const noexcept;
  void bridge_lost_teeth(int k) noexcept;
  void predict(int k) noexcept;  // x ← A_k x (and P in exact mode)
  /// P0 of a (re)start at tooth k: torque states σ², x1 its measurement noise, edge-error states their
  /// variance.
  [[nodiscard]] Mat initial_covariance(int k, double speed_rad_s) const noexcept;
  /// P + B Q Bᵀ after the propagation of tooth k (torque noise u and a fresh edge error at speed ω).
  void add_process_noise(int k, double speed_rad_s, Mat& p) const noexcept;
  /// What a Riccati step at tooth k and speed ω takes from the model besides P: edge_coupling(k),
  /// measurement_var(k, ω), the torque state's process noise and edge_state_var(ω) (constant per APS speed
  /// bin: build_aps_set() computes them once per tooth of the cycle, not per step).
  struct StepNoise {
    double h = 0.0, r = 0.0, q = 0.0, v = 0.0;
  };
  [[nodiscard]] StepNoise step_noise(int k, double speed_rad_s) const noexcept;
  void riccati_step_symmetric(int k, const StepNoise& n, Mat& p, Vec& gain) const noexcept;
  [[nodiscard]] Mat transition(int k) const noexcept;
  /// A_k P A_kᵀ using the sparsity of A_k (per-tooth covariance propagation, CK-13).
  [[nodiscard]] Mat propagate(int k, const Mat& p) const noexcept;

  KalmanParams params_;
  ToothAngleTable table_;
  std::vector<double> a11_, b12_;  ///< per tooth: J_k/J_{k+1}, 2Δ_k/J_{k+1}
  /// Per noise set and tooth [set * K + k]: a = e^{−δΔ_k}, δ = delta (whole torque) or model_delta (model
  /// miss)
  std::vector<double> acol_;
  std::vector<double> qgain_;  ///< the same slots: (1 − a)⁴
  /// Slot of tooth k's pole in acol_ / qgain_ for the current noise set.
  [[nodiscard]] std::size_t set_slot(int k) const noexcept {
    return static_cast<std::size_t>(mode_ * table_.samples + k);
  }
  std::array<double, 2> qu_{};  ///< variance of u (N m)²: [0] whole net torque, [1] the gas model's miss
  std::array<double, 2> sd_{};  ///< the matching stationary 1σ of x2 (P0)
  int mode_ = kWholeTorqueSet;  ///< which of the two the current tooth uses (kModelMissSet: gas model valid)
  std::vector<double> bin_log_speed_;  ///< ln ω of each APS speed bin
  std::vector<double> aps_gain_;       ///< kStates doubles per gain [(set * bins + bin) * K + k]
  [[nodiscard]] Eigen::Map<Vec> aps_gain(std::size_t i) noexcept {
    return Eigen::Map<Vec>(&aps_gain_[i * kStates]);
  }
  [[nodiscard]] Eigen::Map<const Vec> aps_gain(std::size_t i) const noexcept {
    return Eigen::Map<const Vec>(&aps_gain_[i * kStates]);
  }
  std::vector<double> aps_var_;  ///< the same slots: posterior variance of the output state
  double edge_sd_rad_ = 0.0;

  Vec x_ = Vec::Zero();
  Mat p_ = Mat::Zero();
  bool p_finite_ = true;  ///< p_.allFinite() as of its last change (APS: P changes only at a restart)
  Vec last_gain_ = Vec::Zero();
  double last_innovation_ = 0.0;  ///< last_innovation() ((rad/s)²)
  double output_model_nm_ = 0.0;  ///< output_model_nm() (N m)
  TorqueEstimate est_;
  int est_tooth_ = 0;
  bool wheel_learned_ = true;
  double load_star_nm_ = 0.0;
  double mean_speed_ = 0.0;      ///< running mean speed over ≈ one cycle (rad/s), schedules R / gains
  double log_mean_speed_ = 0.0;  ///< ln max(mean_speed_, 1e-3) (APS gains' speed bin)
  int log_fresh_teeth_ = 0;      ///< teeth since log_mean_speed_ was computed exactly
  double inv_samples_ = 0.0;     ///< 1 / samples per cycle
  double bin_scale_ = 0.0;       ///< (bins − 1) / (ln ω_last bin − ln ω_first bin)
  int expected_tooth_ = -1;
  int teeth_seen_ = 0;
  LagRing<std::int64_t, kMaxLag + 1> edge_t_ns_;  ///< edge times of the last teeth, [0] = newest
  double model_next_ = 0.0;                       ///< set_model_torque() for the next tooth
  bool model_next_valid_ = false;
  LagRing<double, kMaxLag + 1> model_;  ///< model ripple of the last steps, [0] = newest
  KalmanStats stats_;
};

}  // namespace torqued
