#include "fuel_angle_window.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;
// The angles per tooth are within one turn of [0, 4π): those take no fmod (six per tooth were half of
// on_tooth). Same bits: fmod is exact, and a − 4π for a in [4π, 8π) is exact too (Sterbenz).
double wrap4pi(double a) noexcept {
  if (a >= 0.0 && a < kFourPi) return a;
  if (a >= kFourPi && a < 2.0 * kFourPi) return a - kFourPi;
  if (a < 0.0 && a > -kFourPi) return a + kFourPi;
  a = std::fmod(a, kFourPi);
  return a < 0.0 ? a + kFourPi : a;
}
}  // namespace

FuelAngleWindow::FuelAngleWindow(int cylinders, const std::array<double, kMaxCylinders>& tdc_rad,
                                 double intake_btdc_deg, double work_centroid_atdc_deg,
                                 double report_window_s) noexcept
    : n_(std::clamp(cylinders, 1, kMaxCylinders)),
      lead_rad_((intake_btdc_deg + work_centroid_atdc_deg) * kDeg),
      report_window_ns_(static_cast<std::int64_t>(std::max(0.0, report_window_s) * 1e9)) {
  for (int m = 0; m < n_; ++m) {
    const auto i = static_cast<std::size_t>(m);
    intake_rel_[i] = wrap4pi(tdc_rad[i] - intake_btdc_deg * kDeg);
  }
  reset();
}

void FuelAngleWindow::reset() noexcept {
  for (auto& c : ev_) c.fill(Event{});
  unwrapped_ = prev_rel_ = last_fuel_kg_ = 0.0;
  open_ = -1;
  have_prev_ = false;
  any_pending_ = false;
}

// A report consistent with one injection decision: the cut-off flag set with no fuel, or clear with fuel.
void FuelAngleWindow::revise(Event& e, const FuelIntakeInput& in) noexcept {
  if (!e.in.valid) return;
  if (in.fuel_cut && !(in.fuel_kg > 0.0)) {
    e.in.fuel_cut = true;
    e.fuel_pending = false;
  } else if (!in.fuel_cut && in.fuel_kg > 0.0) {
    e.in.fuel_cut = false;
    e.in.fuel_kg = in.fuel_kg;
    e.fuel_pending = false;
  }
}

// Real-time safe.
void FuelAngleWindow::on_tooth(std::int64_t t_ns, double rel_rad, const FuelIntakeInput& in) noexcept {
  if (!std::isfinite(rel_rad)) return;
  rel_rad = wrap4pi(rel_rad);
  if (!have_prev_) {
    unwrapped_ = prev_rel_ = rel_rad;  // unwrapped_ stays congruent to the relative angle mod 4π
    have_prev_ = true;
    return;
  }
  const double d = wrap4pi(rel_rad - prev_rel_);
  const bool fuel_report = in.valid && in.fuel_kg > 0.0;
  if (fuel_report) last_fuel_kg_ = in.fuel_kg;
  if (open_ >= 0 && in.valid && t_ns <= open_until_ns_ && unwrapped_ + d <= open_until_rad_)
    revise(ev_[static_cast<std::size_t>(open_)][0], in);
  // A report fills the pending events (only when one may exist: the flag is set with any pending event and
  // cleared by this pass, which leaves none; a pending event is created only without a report, below).
  if (fuel_report && any_pending_) {
    for (int m = 0; m < n_; ++m) {
      for (Event& e : ev_[static_cast<std::size_t>(m)]) {
        if (e.fuel_pending) {
          e.in.fuel_kg = in.fuel_kg;
          e.fuel_pending = false;
        }
      }
    }
    any_pending_ = false;
  }
  double newest_x = -1.0;
  for (int m = 0; m < n_; ++m) {
    const auto i = static_cast<std::size_t>(m);
    auto& c = ev_[i];
    const double x = wrap4pi(intake_rel_[i] - prev_rel_);
    if (!(x > 0.0 && x <= d)) continue;
    for (std::size_t k = c.size() - 1; k > 0; --k) c[k] = c[k - 1];
    c[0] = Event{unwrapped_ + x + lead_rad_, in, true, in.valid && !in.fuel_cut && !fuel_report};
    any_pending_ = any_pending_ || c[0].fuel_pending;
    if (x > newest_x) {
      newest_x = x;
      open_ = m;
      open_until_ns_ = t_ns + report_window_ns_;
      open_until_rad_ = unwrapped_ + x + kFourPi / (2.0 * n_);
    }
  }
  unwrapped_ += d;
  prev_rel_ = rel_rad;
}

// Real-time safe.
FuelWindow FuelAngleWindow::window(double end_rel_rad) const noexcept {
  FuelWindow w;
  if (!have_prev_ || !std::isfinite(end_rel_rad)) return w;
  constexpr double kEps = 1e-9;
  const double end = unwrapped_ - wrap4pi(prev_rel_ - end_rel_rad);
  w.fuel_min_kg = w.map_min_pa = 1e300;
  w.fuel_max_kg = w.map_max_pa = -1e300;
  for (int m = 0; m < n_; ++m) {
    const Event* e = nullptr;
    for (const Event& c : ev_[static_cast<std::size_t>(m)]) {
      if (c.set && c.centroid_rad <= end + kEps) {
        e = &c;
        break;
      }
    }
    // The cylinder's work in this window comes from an event we saw with valid inputs, or the window is
    // unknown.
    if (e == nullptr || e->centroid_rad <= end - kFourPi + kEps || !e->in.valid) return FuelWindow{};
    w.map_min_pa = std::min(w.map_min_pa, e->in.map_pa);
    w.map_max_pa = std::max(w.map_max_pa, e->in.map_pa);
    if (e->in.fuel_cut) {
      ++w.cut;
      w.map_cut_pa += e->in.map_pa;
    } else {
      const double fuel = e->fuel_pending ? last_fuel_kg_ : e->in.fuel_kg;
      ++w.fired;
      w.fuel_kg += fuel;
      w.map_fired_pa += e->in.map_pa;
      w.fuel_min_kg = std::min(w.fuel_min_kg, fuel);
      w.fuel_max_kg = std::max(w.fuel_max_kg, fuel);
    }
  }
  if (w.fired > 0) {
    w.fuel_kg /= w.fired;
    w.map_fired_pa /= w.fired;
  } else {
    w.fuel_min_kg = w.fuel_max_kg = 0.0;
  }
  if (w.cut > 0) w.map_cut_pa /= w.cut;
  w.valid = true;
  return w;
}

}  // namespace torqued
