// Crank decoder cam phase. See cam_phase.hpp.
#include "cam_phase.hpp"

#include <algorithm>
#include <cmath>

#include "crank_decoder.hpp"

namespace torqued {
namespace {
bool in_window_deg(double pos_deg, double start_deg, double end_deg) noexcept {
  pos_deg = std::fmod(pos_deg, 720.0);
  if (pos_deg < 0.0) pos_deg += 720.0;
  if (start_deg <= end_deg) return pos_deg >= start_deg && pos_deg < end_deg;
  return pos_deg >= start_deg || pos_deg < end_deg;  // window wraps through 720°/0°
}
}  // namespace

CamPhase::CamPhase(const DecoderParams& p) noexcept { reset(p); }

void CamPhase::reset(const DecoderParams& p) noexcept {
  known_ = false;
  win_start_ = p.cam_window_start_deg;
  win_end_ = p.cam_window_end_deg;
  angle_deg_ = -1.0;
  learned_ = false;
  learn_n_ = 0;
  learn_first_ = learn_sum_ = 0.0;
}

CamPhase::Result CamPhase::on_edge(double a_deg, int& rev, const DecoderParams& p) noexcept {
  if (p.cam_window_auto && !learned_ && !learn_step(a_deg, rev, p)) return Result::kLearning;
  const bool in_this = in_window_deg(a_deg + 360.0 * rev, win_start_, win_end_);
  const bool in_other = in_window_deg(a_deg + 360.0 * (rev ^ 1), win_start_, win_end_);
  if (!p.cam_window_auto) angle_deg_ = a_deg + 360.0 * (in_this ? rev : rev ^ 1);
  if (in_this && (!in_other || known_)) {
    known_ = true;
    return Result::kInPhase;
  }
  if (in_other && !in_this) {
    const bool was_known = known_;
    rev ^= 1;
    known_ = true;
    return was_known ? Result::kFlipped : Result::kInPhase;
  }
  return Result::kOutside;
}

// cam_window: auto. a_deg: the cam edge's angle within the revolution. Returns true once learned (the window
// is then set around the mean angle, in the revolution of the first learning edge = revolution 0).
bool CamPhase::learn_step(double a_deg, int& rev, const DecoderParams& p) noexcept {
  double d = std::fmod(a_deg - learn_first_ + 540.0, 360.0) - 180.0;
  if (learn_n_ == 0 || std::abs(d) > p.cam_auto_spread_deg) {  // (re)start
    learn_n_ = 0;
    learn_first_ = a_deg;
    learn_sum_ = 0.0;
    d = 0.0;
    rev = 0;  // this edge's revolution is revolution 0
  }
  learn_sum_ += d;
  if (++learn_n_ < std::max(1, p.cam_auto_edges)) return false;
  const double a = std::fmod(learn_first_ + learn_sum_ / learn_n_ + 360.0, 360.0);
  learned_ = true;
  angle_deg_ = a;
  win_start_ = std::fmod(a - 90.0 + 720.0, 720.0);
  win_end_ = a + 90.0;
  return true;
}

}  // namespace torqued
