#include "cycle_ke_window.hpp"

#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;
double diff720(double a, double b) noexcept {
  double d = std::fmod(a - b, kFourPi);
  if (d < 0.0) d += kFourPi;
  return d >= kTwoPi ? d - kFourPi : d;
}
}  // namespace

CycleKeWindow::CycleKeWindow(const CycleEnergy& g, double window_deg, double end_deg)
    : samples_(g.samples()) {
  const auto n = static_cast<std::size_t>(samples_);
  j_center_.resize(n);
  width_.resize(n);
  in_.assign(n, 0);
  last_.assign(n, 0);
  if (!(window_deg > 0.0) || !std::isfinite(window_deg) || window_deg >= 360.0 || !std::isfinite(end_deg))
    return;
  const double b0 = g.boundary_rad(0);
  const double hi = end_deg * kDeg, lo = hi - window_deg * kDeg;
  constexpr double kEps = 1e-9;  // same half-open convention as CycleEnergy's windows
  for (int k = 0; k < samples_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    j_center_[i] = g.inertia_center(k);
    width_[i] = g.nominal_width_rad(k);
    const double d = diff720(g.center_rad(k) + kEps, b0);
    if (d >= lo && d < hi) {
      in_[i] = 1;
      ++expected_;
    }
  }
  for (int k = 0; k < samples_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (in_[i] && !in_[static_cast<std::size_t>((k + 1) % samples_)]) last_[i] = 1;
  }
  reset();
}

void CycleKeWindow::reset() noexcept {
  prev_tooth_ = -1;
  count_ = 0;
  sum_w_ = sum_wke_ = 0.0;
  ke_j_ = d_ke_j_ = 0.0;
  ke_ok_ = d_ke_ok_ = false;
}

// Sequence break: the open window and the previous one are no longer comparable.
void CycleKeWindow::restart(int tooth) noexcept {
  count_ = 0;
  sum_w_ = sum_wke_ = 0.0;
  ke_ok_ = false;
  prev_tooth_ = tooth;
}

bool CycleKeWindow::update(const ToothSample& s) noexcept {
  if (expected_ == 0) return false;
  const bool ok = s.synced && s.tooth >= 0 && s.tooth < samples_ && s.dt_s > 0.0 && s.width_rad > 0.0 &&
                  std::isfinite(s.dt_s) && std::isfinite(s.width_rad);
  if (!ok) {
    restart(-1);
    return false;
  }
  return update_checked(s);
}

// update() after its sample checks (AnglePipeline::on_tooth makes the same ones once per tooth).
bool CycleKeWindow::update_checked(const ToothSample& s) noexcept {
  if (expected_ == 0) return false;
  if (prev_tooth_ >= 0 && s.tooth != (prev_tooth_ + 1 == samples_ ? 0 : prev_tooth_ + 1)) {
    restart(s.tooth);
  } else {
    prev_tooth_ = s.tooth;
  }
  const auto i = static_cast<std::size_t>(s.tooth);
  if (!in_[i]) return false;
  const double speed = s.width_rad / s.dt_s;
  sum_w_ += width_[i];
  sum_wke_ +=
      width_[i] * 0.5 * j_center_[i] * speed * speed;  // angle-weighted (nominal widths), as CycleEnergy
  ++count_;
  if (!last_[i]) return false;
  const bool complete = count_ == expected_;
  const double ke = complete ? sum_wke_ / sum_w_ : 0.0;
  d_ke_ok_ = complete && ke_ok_;
  d_ke_j_ = d_ke_ok_ ? ke - ke_j_ : 0.0;
  ke_j_ = ke;
  ke_ok_ = complete;
  count_ = 0;
  sum_w_ = sum_wke_ = 0.0;
  return true;
}

}  // namespace torqued
