#include "tooth_preprocessor.hpp"

#include <cmath>
#include <mutex>
#include <numbers>
#include <optional>
#include <utility>

#include "table_cache.hpp"

namespace torqued {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;
}  // namespace

void ToothAngleTable::wheel_edges(const WheelGeometry& wheel, std::vector<double>& edge_rad,
                                  std::vector<double>& width_rad) {
  const int teeth = wheel.teeth();
  edge_rad.assign(static_cast<std::size_t>(teeth), 0.0);
  width_rad.assign(static_cast<std::size_t>(teeth), 0.0);
  if (wheel.tooth_count > 0) {
    // Explicit list (irregular wheels): tooth 0 is the first listed edge.
    const double a0 = wheel.tooth_angles_deg[0];
    for (int i = 0; i < teeth; ++i) {
      double a = wheel.tooth_angles_deg[static_cast<std::size_t>(i)] - a0;
      if (a < 0.0) a += 360.0;
      edge_rad[static_cast<std::size_t>(i)] = a * kDeg;
    }
  } else {
    // N−M wheel: teeth at positions 0..T−1, gap of M positions before tooth 0.
    const double pitch = kTwoPi / wheel.positions;
    for (int i = 0; i < teeth; ++i) edge_rad[static_cast<std::size_t>(i)] = i * pitch;
  }
  for (int i = 0; i < teeth; ++i) {
    const double prev = i == 0 ? edge_rad[static_cast<std::size_t>(teeth - 1)] - kTwoPi
                               : edge_rad[static_cast<std::size_t>(i - 1)];
    width_rad[static_cast<std::size_t>(i)] = edge_rad[static_cast<std::size_t>(i)] - prev;
  }
}

ToothAngleTable ToothAngleTable::build(const EngineGeometry& engine, const WheelGeometry& wheel) {
  // Every estimator on the tooth grid builds the same table at start-up: the last one is kept (a copy is
  // returned, the same bytes as a new build).
  static std::mutex mu;
  static std::optional<std::pair<std::uint64_t, ToothAngleTable>> last;
  const std::uint64_t key = TableKey().add(engine).add(wheel).value();
  {
    const std::lock_guard lk(mu);
    if (last && last->first == key) return last->second;
  }
  ToothAngleTable t = build_uncached(engine, wheel);
  const std::lock_guard lk(mu);
  last.emplace(key, t);
  return t;
}

ToothAngleTable ToothAngleTable::build_uncached(const EngineGeometry& engine, const WheelGeometry& wheel) {
  ToothAngleTable t;
  std::vector<double> e1, w1;
  wheel_edges(wheel, e1, w1);
  t.teeth = wheel.teeth();
  t.samples = 2 * t.teeth;
  const auto k_count = static_cast<std::size_t>(t.samples);
  t.edge_rad.resize(k_count);
  t.width_rad.resize(k_count);
  t.step_rad.resize(k_count);
  t.j_center.resize(k_count);
  t.j_edge.resize(k_count);
  t.hdj_edge.resize(k_count);
  const CrankKinematics kin(engine);
  for (int k = 0; k < t.samples; ++k) {
    const auto i = static_cast<std::size_t>(k % t.teeth);
    const auto kk = static_cast<std::size_t>(k);
    const int rev = k / t.teeth;  // whole revolutions before sample k
    t.edge_rad[kk] = rev * kTwoPi + e1[i];
    t.width_rad[kk] = w1[i];
  }
  for (int k = 0; k < t.samples; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    const auto kn = static_cast<std::size_t>((k + 1) % t.samples);
    t.step_rad[kk] = 0.5 * (t.width_rad[kk] + t.width_rad[kn]);
    // Kinematics are indexed by the angle after cylinder 1's firing TDC.
    const double e_tdc = t.edge_rad[kk] - engine.tdc_offset_rad;
    const double c_tdc = e_tdc - 0.5 * t.width_rad[kk];
    t.j_center[kk] = kin.inertia(c_tdc);
    t.j_edge[kk] = kin.inertia(e_tdc);
    t.hdj_edge[kk] = kin.half_dinertia(e_tdc);
  }
  return t;
}

ToothPreprocessor::ToothPreprocessor(const EngineGeometry& engine, const WheelGeometry& wheel,
                                     const PreprocessParams& params)
    : table_(ToothAngleTable::build(engine, wheel)),
      params_(params),
      edge_var2_(2.0 * (params.edge_noise_deg * kDeg) * (params.edge_noise_deg * kDeg)),
      jitter2_(2.0 * params.jitter_s * params.jitter_s),
      lp_rate_(-2.0 * std::numbers::pi * params.lowpass_hz),
      jerk_q_(params.accel_jerk_sd * params.accel_jerk_sd) {}

void ToothPreprocessor::reset() noexcept {
  out_ = ToothKinematics{};
  have_prev_ = false;
  kf_x_[0] = kf_x_[1] = 0.0;
  kf_p_[0] = kf_p_[1] = kf_p_[2] = 0.0;
  prev_center_ns_ = 0;
}

double ToothPreprocessor::speed_sq_rel_sd(double width_rad, double speed_rad_s, double edge_sd_rad,
                                          double jitter_s) noexcept {
  const double angle_var = 2.0 * edge_sd_rad * edge_sd_rad;
  const double time_var = 2.0 * jitter_s * jitter_s * speed_rad_s * speed_rad_s;
  return 2.0 * std::sqrt(angle_var + time_var) / width_rad;
}

bool ToothPreprocessor::update(const ToothSample& s) noexcept {
  if (!s.synced) {
    ++stats_.not_synced;
    out_.valid = false;
    have_prev_ = false;
    return false;
  }
  if (!(s.dt_s > 0.0) || !(s.width_rad > 0.0) || !std::isfinite(s.dt_s) || !std::isfinite(s.width_rad) ||
      s.tooth < 0 || s.tooth >= table_.samples) {
    ++stats_.invalid;
    out_.valid = false;
    have_prev_ = false;
    return false;
  }
  return update_checked(s);
}

// update() after its sample checks (AnglePipeline::on_tooth makes the same ones once per tooth).
bool ToothPreprocessor::update_checked(const ToothSample& s) noexcept {
  ++stats_.accepted;
  const double omega = s.width_rad / s.dt_s;
  out_.t_ns = s.t_ns;
  out_.tooth = s.tooth;
  out_.speed_rad_s = omega;
  out_.speed_sq = omega * omega;
  // The period's mean speed belongs to its centre time (second-order accurate).
  const std::int64_t center_ns = s.t_ns - static_cast<std::int64_t>(0.5e9 * s.dt_s);
  // Measurement variance of θ̇: (½ speed_sq_rel_sd · ω)² = (2σ_a² + 2σ_t²ω²)·(ω/w)² = (2σ_a² + 2σ_t²ω²)/dt²
  // (the square root and the width division of speed_sq_rel_sd cancel; the same value up to rounding).
  const double var_sum = edge_var2_ + jitter2_ * omega * omega;
  const double r = var_sum / (s.dt_s * s.dt_s) + 1e-12;
  if (!have_prev_) {
    out_.speed_lp_rad_s = omega;
    kf_x_[0] = omega;
    kf_x_[1] = 0.0;
    kf_p_[0] = r;
    kf_p_[1] = 0.0;
    kf_p_[2] = 1e8;  // θ̈ unknown: (10^4 rad/s²)²
    have_prev_ = true;
    prev_center_ns_ = center_ns;
    out_.speed_kf_rad_s = omega;
    out_.accel_rad_s2 = 0.0;
    out_.valid = false;
    return true;
  }
  const double h = 1e-9 * static_cast<double>(center_ns - prev_center_ns_);
  prev_center_ns_ = center_ns;
  // Exact first-order low-pass: y += (1 − e^{−2π f_c h})(x − y).
  out_.speed_lp_rad_s += (1.0 - std::exp(lp_rate_ * h)) * (omega - out_.speed_lp_rad_s);
  // [θ̇, θ̈] Kalman filter, constant-acceleration model with white jerk q (Energies 2019 §2.1 uses a KF for θ̈):
  // F = [[1, h], [0, 1]], Q = q [[h³/3, h²/2], [h²/2, h]], measurement θ̇ with variance r.
  const double q = jerk_q_;
  const double x0 = kf_x_[0] + h * kf_x_[1];
  const double x1 = kf_x_[1];
  const double p00 = kf_p_[0] + 2.0 * h * kf_p_[1] + h * h * kf_p_[2] + q * h * h * h / 3.0;
  const double p01 = kf_p_[1] + h * kf_p_[2] + q * h * h / 2.0;
  const double p11 = kf_p_[2] + q * h;
  const double sres = p00 + r;
  const double k0 = p00 / sres;
  const double k1 = p01 / sres;
  const double innov = omega - x0;
  kf_x_[0] = x0 + k0 * innov;
  kf_x_[1] = x1 + k1 * innov;
  kf_p_[0] = (1.0 - k0) * p00;
  kf_p_[1] = (1.0 - k0) * p01;
  kf_p_[2] = p11 - k1 * p01;
  if (!std::isfinite(kf_x_[0]) || !std::isfinite(kf_x_[1])) {
    ++stats_.invalid;
    have_prev_ = false;
    out_.valid = false;
    return false;
  }
  out_.speed_kf_rad_s = kf_x_[0];
  out_.accel_rad_s2 = kf_x_[1];
  out_.valid = true;
  return true;
}

}  // namespace torqued
