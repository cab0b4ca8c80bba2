#include "burn_phase_learner.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "tooth_preprocessor.hpp"

namespace torqued {

namespace {
constexpr double kRadToDeg = 180.0 / std::numbers::pi;
}  // namespace

BurnPhaseLearner::BurnPhaseLearner(const EngineGeometry& engine, const WheelGeometry& wheel,
                                   const BurnPhaseParams& params)
    : p_(params), order_(0.5 * engine.cylinders) {
  const ToothAngleTable t = ToothAngleTable::build(engine, wheel);
  samples_ = t.samples;
  wcos_.resize(static_cast<std::size_t>(samples_));
  wsin_.resize(static_cast<std::size_t>(samples_));
  for (int k = 0; k < samples_; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double psi = order_ * t.edge_rad[i];  // the step [c_k, c_{k+1}] is centred on edge e_k
    wcos_[i] = t.step_rad[i] * std::cos(psi);
    wsin_[i] = t.step_rad[i] * std::sin(psi);
  }
  reset();
}

void BurnPhaseLearner::reset() noexcept {
  offset_deg_ = std::clamp(0.0, p_.min_offset_deg, p_.max_offset_deg);
  stats_ = BurnPhaseStats{};
  imported_cycles_ = 0;
  prev_cut_ = false;
  clear_cycle();
}

void BurnPhaseLearner::clear_cycle() noexcept {
  e_re_ = e_im_ = m_re_ = m_im_ = 0.0;
  count_ = 0;
  all_map_ = all_spark_ = all_model_ = true;
  any_cut_ = false;
}

// Real-time safe: two multiply-adds per sum.
void BurnPhaseLearner::update(int tooth, double estimate_nm, double model_nm, bool valid) noexcept {
  if (tooth < 0 || tooth >= samples_) return;
  all_map_ = all_map_ && map_ok_;
  all_spark_ = all_spark_ && spark_ok_;
  any_cut_ = any_cut_ || cut_;
  const bool sample_ok = valid && std::isfinite(estimate_nm) && std::isfinite(model_nm);
  all_model_ = all_model_ && sample_ok;
  if (!sample_ok) return;
  const auto i = static_cast<std::size_t>(tooth);
  e_re_ += wcos_[i] * estimate_nm;
  e_im_ -= wsin_[i] * estimate_nm;
  m_re_ += wcos_[i] * model_nm;
  m_im_ -= wsin_[i] * model_nm;
  ++count_;
}

// Real-time safe: one atan2 per cycle.
bool BurnPhaseLearner::end_cycle() noexcept {
  const bool cut_in_or_before = any_cut_ || prev_cut_;
  prev_cut_ = any_cut_;
  const bool complete = count_ == samples_;
  // |M_h|: the sums are integrals over 4π of M·e^{−iψ}, so a component A cos(...) gives A·2π.
  const double ripple_amp_nm = std::hypot(m_re_, m_im_) / (2.0 * std::numbers::pi);
  const bool ripple_defined = ripple_amp_nm >= p_.min_ripple_nm;
  const double e_re = e_re_, e_im = e_im_, m_re = m_re_, m_im = m_im_;
  bool gates_pass = false;
  if (cut_in_or_before) {
    ++stats_.cycles_cutoff;
  } else if (!all_map_) {
    ++stats_.cycles_no_map;
  } else if (!all_spark_) {
    ++stats_.cycles_no_spark;
  } else if (!all_model_) {
    ++stats_.cycles_no_model;
  } else if (!complete) {
    ++stats_.cycles_incomplete;
  } else if (!ripple_defined) {
    ++stats_.cycles_small_ripple;
  } else {
    gates_pass = true;
  }
  clear_cycle();
  if (!gates_pass || !p_.learn) return false;
  // d = arg(E_h · conj(M_h)) / h: the model's lag behind the estimate (crank deg).
  const double re = e_re * m_re + e_im * m_im;
  const double im = e_im * m_re - e_re * m_im;
  const double d_deg = std::atan2(im, re) / order_ * kRadToDeg;
  if (!std::isfinite(d_deg)) return false;
  ++stats_.cycles_used;
  stats_.last_phase_deg = d_deg;
  const double a = 1.0 / std::max(p_.quality_cycles, 1);
  stats_.mean_phase_deg =
      stats_.cycles_used == 1 ? d_deg : stats_.mean_phase_deg + a * (d_deg - stats_.mean_phase_deg);
  const double step = std::clamp(-p_.gain * d_deg, -p_.max_step_deg, p_.max_step_deg);
  const double before = offset_deg_;
  offset_deg_ = std::clamp(offset_deg_ + step, p_.min_offset_deg, p_.max_offset_deg);
  stats_.state = quality();
  return offset_deg_ != before;
}

BurnPhaseState BurnPhaseLearner::quality() const noexcept {
  if (stats_.cycles_used == 0)
    return imported_cycles_ > 0 || offset_deg_ != 0.0 ? BurnPhaseState::kImported : BurnPhaseState::kNotUsed;
  const bool enough = stats_.cycles_used + imported_cycles_ >= static_cast<std::uint64_t>(p_.min_cycles);
  const bool agrees = std::abs(stats_.mean_phase_deg) <= p_.converged_deg;
  return enough && agrees ? BurnPhaseState::kConverged : BurnPhaseState::kLearning;
}

bool BurnPhaseLearner::import_state(double offset_deg, double cycles_used) noexcept {
  const bool in_bounds = std::isfinite(offset_deg) && offset_deg >= p_.min_offset_deg &&
                         offset_deg <= p_.max_offset_deg && std::isfinite(cycles_used) && cycles_used >= 0.0;
  if (!in_bounds) return false;
  offset_deg_ = offset_deg;
  imported_cycles_ = static_cast<std::uint64_t>(cycles_used);
  stats_.state = quality();
  return true;
}

}  // namespace torqued
