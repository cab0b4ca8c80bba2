#include "can_encoder.hpp"

#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace torqued {

const char* validate(const CanEncoderConfig& cfg) noexcept {
  if (cfg.extended ? cfg.id > 0x1FFFFFFFu : cfg.id > 0x7FFu) {
    return "encoder id out of range (standard: 0..0x7FF, extended: 0..0x1FFFFFFF)";
  }
  if (cfg.tick_ns < 1 || cfg.tick_ns > 1'000'000) return "encoder tick_ns must be 1 .. 1000000 ns";
  if (cfg.crank_channel == cfg.cam_channel) return "encoder crank_channel and cam_channel must differ";
  if (!(cfg.max_slew_ppm >= 0.0 && cfg.max_slew_ppm <= 10000.0))
    return "encoder max_slew_ppm must be 0 .. 10000";
  if (cfg.align_window_frames < 8 || cfg.align_window_frames > 100000) {
    return "encoder align_window_frames must be 8 .. 100000";
  }
  return nullptr;
}

namespace can_encoder {

std::uint8_t fd_length(std::size_t len) noexcept {
  if (len <= 8) return static_cast<std::uint8_t>(len);
  static constexpr std::uint8_t kLens[] = {12, 16, 20, 24, 32, 48, 64};
  for (std::uint8_t l : kLens) {
    if (len <= l) return l;
  }
  return 64;
}

std::size_t encode_frame(const EdgeEvent* edges, std::size_t n, std::uint8_t seq, std::uint8_t flags,
                         const CanEncoderConfig& cfg, CanFrame& out) noexcept {
  const std::size_t cap = static_cast<std::size_t>(max_entries(cfg));
  if (n > cap) n = cap;
  out = CanFrame{};
  out.id = cfg.id;
  out.extended = cfg.extended;
  out.fd = cfg.fd;
  out.data[0] = seq;
  out.data[1] = static_cast<std::uint8_t>((flags & (kFlagRestart | kFlagOverflow)) | (n & 0x0Fu));
  for (std::size_t k = 0; k < n; ++k) {
    const EdgeEvent& e = edges[k];
    const std::int64_t ticks = e.t_ns / cfg.tick_ns;
    std::uint32_t w = static_cast<std::uint32_t>(static_cast<std::uint64_t>(ticks) & kTickMask);
    if (e.level != 0) w |= 1u << 30;
    if (e.channel == cfg.cam_channel) w |= 1u << 31;
    std::uint8_t* p = out.data.data() + 2 + 4 * k;
    p[0] = static_cast<std::uint8_t>(w);
    p[1] = static_cast<std::uint8_t>(w >> 8);
    p[2] = static_cast<std::uint8_t>(w >> 16);
    p[3] = static_cast<std::uint8_t>(w >> 24);
    out.t_ns = e.t_ns;
  }
  const std::size_t len = 2 + 4 * n;
  out.len = cfg.fd ? fd_length(len) : static_cast<std::uint8_t>(len);
  return n;
}

const char* decode_frame(const CanFrame& frame, const CanEncoderConfig& cfg, FrameView& out) noexcept {
  if (frame.len < 2) return "at least 2 bytes (sequence counter, entry count)";
  out.seq = frame.data[0];
  out.flags = static_cast<std::uint8_t>(frame.data[1] & (kFlagRestart | kFlagOverflow));
  out.n = frame.data[1] & 0x0F;
  if ((frame.data[1] & 0x30u) != 0) return "reserved bits 4-5 of byte 1 to be zero";
  const int cap = frame.fd ? kMaxEntriesFd : kMaxEntriesClassic;
  (void)cfg;
  if (out.n > cap)
    return frame.fd ? "at most 15 entries in a CAN FD frame" : "at most 1 entry in a classic frame";
  if (frame.len < 2 + 4 * out.n) return "frame length >= 2 + 4 x entry count";
  for (int k = 0; k < out.n; ++k) {
    const std::uint8_t* p = frame.data.data() + 2 + 4 * k;
    const std::uint32_t w = static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
                            (static_cast<std::uint32_t>(p[2]) << 16) |
                            (static_cast<std::uint32_t>(p[3]) << 24);
    out.entries[static_cast<std::size_t>(k)] =
        Entry{w & kTickMask, static_cast<std::uint8_t>((w >> 30) & 1u), ((w >> 31) & 1u) != 0};
  }
  return nullptr;
}

bool Batcher::emit(CanFrame& out) noexcept {
  if (n_ == 0) return false;
  encode_frame(pending_.data(), static_cast<std::size_t>(n_), seq_, 0, cfg_, out);
  ++seq_;  // wraps mod 256
  ++frames_;
  n_ = 0;
  return true;
}

bool Batcher::push(const EdgeEvent& edge, CanFrame& out) noexcept {
  bool emitted = false;
  if (n_ > 0 && edge.t_ns - pending_[0].t_ns > max_latency_ns_) emitted = emit(out);
  pending_[static_cast<std::size_t>(n_++)] = edge;
  if (!emitted && n_ == max_entries(cfg_)) emitted = emit(out);
  // If a latency flush happened and the new edge alone fills a frame (classic), it stays pending until the
  // next push/flush: at most one frame is produced per call.
  return emitted;
}

bool Batcher::flush(CanFrame& out) noexcept { return emit(out); }

}  // namespace can_encoder

CanEncoderEdgeSource::CanEncoderEdgeSource(CanSource& can, const CanEncoderConfig& cfg)
    : can_(can), cfg_(cfg) {
  if (const char* why = validate(cfg)) error_ = why;
}

std::string CanEncoderEdgeSource::describe() const {
  char buf[160];
  std::snprintf(buf, sizeof buf, "can-encoder id=0x%X%s %s tick=%lld ns over ",
                static_cast<unsigned>(cfg_.id), cfg_.extended ? "x" : "", cfg_.fd ? "fd" : "classic",
                static_cast<long long>(cfg_.tick_ns));
  return buf + can_.describe();
}

std::string CanEncoderEdgeSource::last_error() const {
  if (!error_.empty()) return error_;
  return std::string(bad_msg_.data());
}

void CanEncoderEdgeSource::accept(const CanFrame& frame) noexcept {
  using namespace can_encoder;
  if (const char* why = decode_frame(frame, cfg_, view_)) {
    ++enc_.bad_frames;
    ++stats_.bad_lines;
    std::snprintf(bad_msg_.data(), bad_msg_.size(), "encoder frame %llu (t=%lld ns): expected %s",
                  static_cast<unsigned long long>(enc_.frames + enc_.bad_frames),
                  static_cast<long long>(frame.t_ns), why);
    return;
  }
  ++enc_.frames;
  if (have_seq_) {
    const std::uint8_t expected = static_cast<std::uint8_t>(last_seq_ + 1);
    if (view_.seq == last_seq_ && (view_.flags & kFlagRestart) == 0) {
      ++enc_.duplicate_frames;
      return;
    }
    if (view_.seq != expected) {
      const std::uint8_t lost = static_cast<std::uint8_t>(view_.seq - expected);
      ++enc_.sequence_errors;
      enc_.lost_frames += lost;
      stats_.dropped += lost;
    }
  }
  have_seq_ = true;
  last_seq_ = view_.seq;
  if (view_.flags & kFlagOverflow) ++enc_.overflow_flags;
  const bool restart = (view_.flags & kFlagRestart) != 0;
  if (restart) ++enc_.restarts;

  constexpr std::int64_t kWrap = std::int64_t{1} << kTickBits;
  for (int k = 0; k < view_.n; ++k) {
    const Entry& e = view_.entries[static_cast<std::size_t>(k)];
    std::int64_t ticks = 0;
    if (!have_time_) {
      ticks = e.ticks;  // first entry: the encoder's own origin
    } else {
      const std::int64_t rx_dt_ticks = (frame.t_ns - last_rx_ns_) / cfg_.tick_ns;
      std::int64_t delta =
          (static_cast<std::int64_t>(e.ticks) - static_cast<std::int64_t>(last_raw_)) & (kWrap - 1);
      if (restart && k == 0) {
        // New encoder origin: continue the time line from the receive-time gap (at least one tick).
        delta = rx_dt_ticks > 0 ? rx_dt_ticks : 1;
        ticks = last_ticks_ + delta;
      } else if (rx_dt_ticks >= kWrap / 2) {
        // Long pause: the receive-time gap says how many whole wraps passed.
        const std::int64_t wraps = (rx_dt_ticks - delta + kWrap / 2) / kWrap;
        ticks = last_ticks_ + delta + wraps * kWrap;
        ++enc_.long_pauses;
      } else {
        if (delta >= kWrap / 2) {  // negative step: entry earlier than the previous one
          ++enc_.backwards;
          ++stats_.bad_lines;
          continue;
        }
        ticks = last_ticks_ + delta;
      }
    }
    have_time_ = true;
    last_ticks_ = ticks;
    last_raw_ = e.ticks;
    last_rx_ns_ = frame.t_ns;
    EdgeEvent& out = out_[static_cast<std::size_t>(out_n_++)];
    out.t_ns = ticks * cfg_.tick_ns;  // encoder clock; offsets are added below, once the whole frame is known
    out.channel = e.cam ? cfg_.cam_channel : cfg_.crank_channel;
    out.level = e.level;
  }
  if (cfg_.align_to_receive_time && out_n_ > 0) align(frame.t_ns);
  for (int k = 0; k < out_n_; ++k) out_[static_cast<std::size_t>(k)].t_ns += cfg_.time_offset_ns;
}

void CanEncoderEdgeSource::align(std::int64_t rx_ns) noexcept {
  // Maps encoder time e onto the receive clock: t = e + offset. The receive latency rx − e_last of a frame is
  // transport floor + jitter ≥ floor, so the lower envelope of raw = rx − e_last over a window of frames is
  // the offset we want (up to the constant floor, which time_offset_ns can remove). The envelope's slope is
  // the oscillator drift. The applied offset is never stepped after the first frame: it is slewed at rate =
  // drift + error/window, at most max_slew_ppm, so tooth periods change by at most that rate.
  const std::int64_t e_first = out_[0].t_ns;
  const std::int64_t e_last = out_[static_cast<std::size_t>(out_n_ - 1)].t_ns;
  const double max_rate = cfg_.max_slew_ppm * 1e-6;
  if (!aligned_) {
    aligned_ = true;
    offset_base_ns_ =
        rx_ns - e_last;  // integer part: receive clocks are ~1.7e18 ns, beyond double's ns precision
    offset_ns_ = 0.0;
    slew_ref_ns_ = e_first;
    win_start_ns_ = e_last;
    win_frames_ = 0;
    win_min_ = 1e300;
  }
  for (int k = 0; k < out_n_; ++k) {
    EdgeEvent& out = out_[static_cast<std::size_t>(k)];
    offset_ns_ += rate_ * static_cast<double>(out.t_ns - slew_ref_ns_);
    slew_ref_ns_ = out.t_ns;
    out.t_ns += offset_base_ns_ + static_cast<std::int64_t>(std::llround(offset_ns_));
  }
  const double raw = static_cast<double>(rx_ns - e_last - offset_base_ns_);
  const double detrended = raw - drift_ * static_cast<double>(e_last - win_start_ns_);
  if (detrended < win_min_) win_min_ = detrended;
  if (++win_frames_ < cfg_.align_window_frames) return;
  const double span = static_cast<double>(e_last - win_start_ns_);
  if (span <= 0.0) return;
  const double mid = static_cast<double>(win_start_ns_) + 0.5 * span;
  const double floor_mid = win_min_ + drift_ * 0.5 * span;  // envelope at the window's middle
  if (have_floor_) {
    const double d_meas = (floor_mid - floor_prev_) / (mid - mid_prev_);
    drift_ += 0.5 * (d_meas - drift_);
    if (drift_ > max_rate) drift_ = max_rate;
    if (drift_ < -max_rate) drift_ = -max_rate;
  }
  have_floor_ = true;
  floor_prev_ = floor_mid;
  mid_prev_ = mid;
  const double error = floor_mid + drift_ * (static_cast<double>(e_last) - mid) - offset_ns_;
  double rate = drift_ + error / span;
  if (rate > max_rate) rate = max_rate;
  if (rate < -max_rate) rate = -max_rate;
  rate_ = rate;
  enc_.align_offset_ns = static_cast<double>(offset_base_ns_) + offset_ns_;
  enc_.align_rate_ppm = rate * 1e6;
  enc_.align_drift_ppm = drift_ * 1e6;
  enc_.align_error_ns = error;
  win_frames_ = 0;
  win_min_ = 1e300;
  win_start_ns_ = e_last;
}

SourceStatus CanEncoderEdgeSource::next(EdgeEvent& out) noexcept {
  if (!error_.empty()) return SourceStatus::kError;
  for (;;) {
    if (out_i_ < out_n_) {
      out = out_[static_cast<std::size_t>(out_i_++)];
      ++stats_.records;
      return SourceStatus::kOk;
    }
    out_i_ = out_n_ = 0;
    CanFrame frame;
    const SourceStatus s = can_.next(frame);
    if (s != SourceStatus::kOk) return s;
    if (frame.id != cfg_.id || frame.extended != cfg_.extended) {
      ++enc_.other_frames;
      continue;
    }
    accept(frame);
  }
}

}  // namespace torqued
