#include "time_stage.hpp"

#include <cmath>

namespace torqued {

// Placeholder until estimators/time_pipeline.hpp lands: no time-domain method runs.
class TimePipelineAdapter {};

TimeStage::TimeStage(const StageSettings& s, const DbcDatabase* dbc, SampleSink& out) : s_(s), out_(out) {
  step_ns_ = static_cast<std::int64_t>(std::llround(s.time_pipeline.step_s * 1e9));
  if (step_ns_ <= 0) error_ = "time pipeline step must be > 0";
  ring_len_ = 2 * s.wheel.teeth();
  if (ring_len_ <= 0 || ring_len_ > static_cast<int>(dt_ring_.size())) error_ = "wheel tooth count out of range";
  if (dbc) {
    store_ = std::make_unique<SignalStore>(*dbc);
    for (int i = 0; i < kSignalCount; ++i) {
      const SignalSpec& spec = s_.signals[static_cast<std::size_t>(i)];
      if (spec.message.empty()) continue;
      std::string err;
      if (!store_->bind(static_cast<Quantity>(i), spec.message, spec.signal, spec.timeout_ns, &err))
        error_ = std::string("signal '") + quantity_name(static_cast<Quantity>(i)) + "': " + err;
    }
  }
}

TimeStage::~TimeStage() = default;

void TimeStage::on_tooth(const ToothSample& t) noexcept {
  if (!t.synced || !(t.dt_s > 0.0)) {
    ring_n_ = ring_i_ = 0;
    sum_dt_ = sum_w_ = 0.0;
    mean_speed_rad_s_ = 0.0;
    return;
  }
  // Sliding sum over the last 720° (ring_len_ teeth): mean speed = Σ width / Σ dt.
  if (ring_n_ == ring_len_) {
    sum_dt_ -= dt_ring_[static_cast<std::size_t>(ring_i_)];
    sum_w_ -= w_ring_[static_cast<std::size_t>(ring_i_)];
  } else {
    ++ring_n_;
  }
  dt_ring_[static_cast<std::size_t>(ring_i_)] = t.dt_s;
  w_ring_[static_cast<std::size_t>(ring_i_)] = t.width_rad;
  sum_dt_ += t.dt_s;
  sum_w_ += t.width_rad;
  ring_i_ = ring_i_ + 1 == ring_len_ ? 0 : ring_i_ + 1;
  mean_speed_rad_s_ = ring_n_ == ring_len_ && sum_dt_ > 0.0 ? sum_w_ / sum_dt_ : 0.0;
  last_tooth_t_ns_ = t.t_ns;
}

void TimeStage::on_frame(const CanFrame& f) noexcept {
  if (store_) (void)store_->on_frame(f);
}

void TimeStage::step(std::int64_t t_ns, std::int64_t ingest_ns) noexcept {
  ++steps_;
  (void)t_ns;
  (void)ingest_ns;
}

}  // namespace torqued
