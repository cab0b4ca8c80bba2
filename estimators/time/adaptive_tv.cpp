#include "adaptive_tv.hpp"

#include <algorithm>
#include <cmath>

namespace torqued {

namespace {
using Mat = AdaptiveTv::Mat;
double det2(const Mat& a) noexcept { return a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0); }
/// Closed-form 2×2 inverse given its determinant (caller checks det ≠ 0).
Mat inv2(const Mat& a, double det) noexcept {
  Mat r;
  r << a(1, 1), -a(0, 1), -a(1, 0), a(0, 0);
  return r / det;
}
}  // namespace

AdaptiveTv::AdaptiveTv(const AdaptiveParams& params, double inertia_kgm2, double step_s) noexcept
    : params_(params), inertia_kgm2_(inertia_kgm2) {
  const auto& g = params_.time_varying_gain ? params_.gamma_tv : params_.gamma;
  gamma_ = Vec(g[0], g[1]).asDiagonal();
  k0_ = Vec(params_.k0[0], params_.k0[1]).asDiagonal();
  scale_ = Vec(params_.phi_scale[0], params_.phi_scale[1]);
  omega_f_.configure(params_.k_s, step_s);
  load_f_.configure(params_.k_s, step_s);
  phi_f_.configure(params_.k_s, step_s);
  set_step(step_s);
  reset();
}

void AdaptiveTv::set_step(double step_s) noexcept {
  if (step_s == step_s_) return;
  step_s_ = step_s;
  decay_ = std::exp(-params_.ell * step_s);
  beta_ = -std::expm1(-params_.ell * step_s) / params_.ell;
}

void AdaptiveTv::reset() noexcept {
  omega_f_.reset(0.0);
  load_f_.reset(0.0);
  phi_f_.reset(Vec::Zero());
  p_.setZero();
  q_.setZero();
  m_ = k0_;  // Na-52: K(0)^-1 = K0
  k_ = inv2(m_, det2(m_));
  theta_ = Vec(params_.theta0[0], params_.theta0[1]);
  y_f_ = 0.0;
  lambda_min_p_ = 0.0;
  primed_ = false;
  running_s_ = 0.0;
  estimate_ = TorqueEstimate{};
}

AdaptiveTv::Vec AdaptiveTv::theta_si() const noexcept { return theta_.cwiseProduct(scale_); }

double AdaptiveTv::lambda_min(const Mat& a) noexcept {
  const double mean = 0.5 * (a(0, 0) + a(1, 1));
  const double half_diff = 0.5 * (a(0, 0) - a(1, 1));
  const double off = 0.5 * (a(0, 1) + a(1, 0));
  return mean - std::hypot(half_diff, off);
}

// A singular step: the estimator resets itself and says so (Health::kNumerical) for this sample.
void AdaptiveTv::fail_numerical(std::int64_t t_ns) noexcept {
  reset();
  estimate_.t_ns = t_ns;
  estimate_.health = Health::kNumerical;
}

void AdaptiveTv::update(const TimeSample& s) noexcept {
  // A bad sample: θ̂, P, Q, K held; the filters restart at the next good one.
  if (!accept_time_sample(s, /*need_maf=*/true, estimate_, primed_)) return;
  const Vec phi(s.speed_rad_s * scale_[0], s.maf_kg_s * scale_[1]);
  if (!primed_) {
    omega_f_.reset(s.speed_rad_s);
    load_f_.reset(s.load_torque_nm);
    phi_f_.reset(phi);
    primed_ = true;
  }
  omega_f_.set_step(s.dt_s);
  load_f_.set_step(s.dt_s);
  phi_f_.set_step(s.dt_s);
  set_step(s.dt_s);

  // Na-44: y_f = J(ω − ω_f)/k + τ_lf, with the filter states at t_n (see uio.cpp).
  const Vec phi_f = phi_f_.state();
  y_f_ = inertia_kgm2_ * omega_f_.gain_per_s() * (s.speed_rad_s - omega_f_.state()) + load_f_.state();
  omega_f_.update(s.speed_rad_s);
  load_f_.update(s.load_torque_nm);
  phi_f_.update(phi);

  // Na-45 and Na-53, exact for φ_f, y_f held over the step.
  const Mat ppt = phi_f * phi_f.transpose();
  const Vec py = phi_f * y_f_;
  p_ = decay_ * p_ + beta_ * ppt;
  q_ = decay_ * q_ + beta_ * py;
  // Symmetrise against round-off (docs/conventions.md habit 12).
  p_(0, 1) = p_(1, 0) = 0.5 * (p_(0, 1) + p_(1, 0));

  const double dt = s.dt_s;
  Mat g = gamma_;
  if (params_.time_varying_gain) {
    m_ = decay_ * m_ + beta_ * ppt + (1.0 - decay_) * params_.k0_floor * k0_;
    m_(0, 1) = m_(1, 0) = 0.5 * (m_(0, 1) + m_(1, 0));
    const double det_m = det2(m_);
    if (!(det_m > 0.0) || !std::isfinite(det_m)) {
      fail_numerical(s.t_ns);
      return;
    }
    k_ = inv2(m_, det_m);
    g = gamma_ * k_;  // Na-54
  }
  // Backward Euler on θ̂̇ = −G(Sθ̂ − b) (Na-50/54 with W1 + κW2 = Sθ̂ − b).
  const Mat sm = p_ + params_.kappa * ppt;
  const Vec b = q_ + params_.kappa * py;
  const Mat a = Mat::Identity() + dt * g * sm;
  const double det_a = det2(a);
  if (!(std::abs(det_a) > 1e-300) || !std::isfinite(det_a)) {
    fail_numerical(s.t_ns);
    return;
  }
  theta_ = inv2(a, det_a) * (theta_ + dt * g * b);

  lambda_min_p_ = lambda_min(p_);
  const double torque = phi.dot(theta_);  // τ̂_e = φᵀθ̂ (Theorem 3/4)
  if (!std::isfinite(torque) || !theta_.allFinite()) {
    fail_numerical(s.t_ns);
    return;
  }
  running_s_ += dt;
  estimate_.torque_nm = torque;
  estimate_.uncertainty = lambda_min_p_;
  const double settle_s = std::max(5.0 * params_.k_s, 5.0 / params_.ell);
  if (running_s_ < settle_s) {
    estimate_.health = Health::kNotConverged;
  } else if (lambda_min_p_ < params_.sigma) {
    estimate_.health = Health::kNotExcited;
  } else {
    estimate_.health = Health::kValid;
  }
}

}  // namespace torqued
