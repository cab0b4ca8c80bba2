#pragma once
// Per-tooth pre-processing for the angle-domain estimators (Energies 2019 §2.1):
// speed from the TRUE angular width of each tooth period, θ̇², a first-order low-pass of the speed and a small
// Kalman filter [θ̇, θ̈] for the acceleration. Also holds `ToothAngleTable`, the per-sample angles and
// kinematics of one 720° cycle for the configured wheel and engine, shared by ChauvinKalman, FourierObserver
// and the tooth-error learner (built once at start-up; no trigonometry per tooth).
#include <cstdint>
#include <vector>

#include "crank_kinematics.hpp"
#include "engine_geometry.hpp"
#include "params.hpp"
#include "samples.hpp"

namespace torqued {

/// Nominal geometry of the K = 2·teeth samples of a 720° cycle. Sample k is the tooth period that ENDS at
/// edge k (ToothSample::tooth == k). Its speed w/dt is the mean over the period, i.e. the speed at the
/// period's centre c_k = e_k − w_k/2 to second order. Between two samples the crank turns Δ_k = c_{k+1} −
/// c_k, whose midpoint is edge e_k: the model steps therefore use the kinematics at e_k (midpoint rule) and J
/// at the centres. Unequal steps (the missing-tooth gap) are handled exactly, so any N−M or explicit wheel
/// works unchanged.
struct ToothAngleTable {
  int samples = 0;  ///< K = 2 × teeth per revolution
  int teeth = 0;    ///< physical teeth per revolution
  std::vector<double>
      edge_rad;  ///< e_k: nominal edge angle in 720°, from tooth 0 (first after the gap) (rad)
  std::vector<double> width_rad;  ///< w_k: nominal width of the period ending at edge k (rad)
  std::vector<double> step_rad;   ///< Δ_k = c_{k+1} − c_k = (w_k + w_{k+1})/2 (rad)
  std::vector<double> j_center;   ///< J(c_k) (kg m²)
  std::vector<double> j_edge;     ///< J(e_k) (kg m²)
  std::vector<double> hdj_edge;   ///< ½J'(e_k) (kg m²/rad)

  /// Builds the table; angles relative to cylinder 1's firing TDC are e_k − geometry.tdc_offset_rad.
  /// Start-up only (allocates; the last table built is kept and returned again for the same geometry).
  static ToothAngleTable build(const EngineGeometry& engine, const WheelGeometry& wheel);
  /// The same without the memo.
  static ToothAngleTable build_uncached(const EngineGeometry& engine, const WheelGeometry& wheel);
  /// Nominal edge angles of one revolution (rad, tooth 0 at 0) and the widths ending at them.
  static void wheel_edges(const WheelGeometry& wheel, std::vector<double>& edge_rad,
                          std::vector<double>& width_rad);
};

/// Output of the pre-processor for one tooth.
struct ToothKinematics {
  std::int64_t t_ns = 0;        ///< edge time (ns)
  int tooth = 0;                ///< sample index k in 720°
  double speed_rad_s = 0.0;     ///< w_k / dt_k: mean speed over the period (rad/s)
  double speed_sq = 0.0;        ///< (w_k/dt_k)² (rad²/s²): the measurement y_k of both Chauvin observers
  double speed_lp_rad_s = 0.0;  ///< first-order low-passed speed (rad/s)
  double accel_rad_s2 = 0.0;    ///< θ̈ from the [θ̇, θ̈] Kalman filter (rad/s²)
  double speed_kf_rad_s = 0.0;  ///< θ̇ from that filter (rad/s)
  bool valid = false;           ///< false until the first two valid teeth or after a rejected sample
};

/// Counters of rejected input (never silent).
struct PreprocessStats {
  std::uint64_t accepted = 0;
  std::uint64_t not_synced = 0;  ///< samples with synced == false (estimators hold)
  std::uint64_t invalid = 0;     ///< non-finite / non-positive dt or width, tooth index out of range
};

class ToothPreprocessor {
 public:
  ToothPreprocessor(const EngineGeometry& engine, const WheelGeometry& wheel, const PreprocessParams& params);

  void reset() noexcept;
  /// Real-time safe. Returns false (and counts) when the sample is rejected; the state is then not valid.
  bool update(const ToothSample& s) noexcept;
  /// update() for a sample already checked as update() does (synced, finite positive dt and width, tooth in
  /// [0, samples)): AnglePipeline::on_tooth checks once per tooth. Real-time safe.
  bool update_checked(const ToothSample& s) noexcept;
  [[nodiscard]] const ToothKinematics& state() const noexcept { return out_; }
  [[nodiscard]] const PreprocessStats& stats() const noexcept { return stats_; }
  [[nodiscard]] const ToothAngleTable& table() const noexcept { return table_; }

  /// Relative 1σ of θ̇² measured over a tooth of width w at speed ω given edge-angle error and jitter:
  /// 2·sqrt(2σ_e²/w² + 2σ_j²ω²/w²) (each width has two independent edges). Used for R of the observers.
  [[nodiscard]] static double speed_sq_rel_sd(double width_rad, double speed_rad_s, double edge_sd_rad,
                                              double jitter_s) noexcept;

 private:
  ToothAngleTable table_;
  PreprocessParams params_;
  ToothKinematics out_;
  PreprocessStats stats_;
  bool have_prev_ = false;
  double kf_x_[2] = {0.0, 0.0};       ///< [θ̇, θ̈]
  double kf_p_[3] = {0.0, 0.0, 0.0};  ///< P00, P01, P11
  std::int64_t prev_center_ns_ = 0;
  // Per-tooth constants of update(), from params_ alone (the same expressions, taken once).
  double edge_var2_;  ///< 2σ_e² (rad²)
  double jitter2_;    ///< 2σ_t² (s²)
  double lp_rate_;    ///< −2π f_c (rad/s)
  double jerk_q_;     ///< q = σ_jerk² ((rad/s³)²)
};

}  // namespace torqued
