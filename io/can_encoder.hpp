#pragma once
// Crank/cam edge timestamps carried in CAN / CAN FD frames by an encoder interface (a small µC that
// timestamps the sensor edges with its own counter and sends them in batches). Layout "torqued encoder v1",
// documented in docs/live.md; all multi-byte fields little-endian:
//
//   byte 0      sequence counter, +1 per frame, mod 256 (gaps = lost frames)
//   byte 1      bits 0-3: n = number of edge entries (CAN FD: 0..15, classic CAN: 0..1)
//               bit 6: encoder restarted (its counter origin changed; the unwrap restarts)
//               bit 7: overflow (the encoder dropped edges before this frame)
//   byte 2+4k   entry k (uint32 LE): bits 0-29 edge time in ticks mod 2^30, bit 30 level after the edge,
//               bit 31 channel (0 = crank, 1 = cam)
//
// Frame length 2 + 4n (classic: 6 bytes for one entry; FD: rounded up to the next valid FD length, padding
// 0). Tick: configurable (default 10 ns → wrap every 10.7 s). The 30-bit times are unwrapped against the
// previous entry; a pause longer than half a wrap is resolved with the frames' receive times
// (CanFrame::t_ns).
//
// encode_frame/decode_frame are pure and real-time safe; CanEncoderEdgeSource turns the frames of any
// CanSource into EdgeEvents (no allocation in next()).
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "records.hpp"
#include "source.hpp"

namespace torqued {

struct CanEncoderConfig {
  std::uint32_t id = 0x300;   ///< CAN identifier of the encoder frames (config inputs.edges.encoder_can_id)
  bool extended = false;      ///< 29-bit identifier
  bool fd = true;             ///< CAN FD frames (up to 15 entries) or classic (1 entry per frame)
  std::int64_t tick_ns = 10;  ///< encoder counter tick (ns), 1 .. 1'000'000
  std::int64_t time_offset_ns = 0;  ///< added to the unwrapped encoder time (maps it onto the edge clock)
  /// Live use: put the edges on the clock of the frames' receive times (SocketCAN: CLOCK_REALTIME), so tooth
  /// times and CAN signal times compare. The offset is set at the first frame and then slewed (never stepped,
  /// at most max_slew_ppm) so that the smallest receive latency seen in each window of frames goes to zero;
  /// this follows the drift between the encoder's oscillator and the host clock.
  bool align_to_receive_time = false;
  double max_slew_ppm = 200.0;     ///< largest rate correction of the alignment (ppm), 0 .. 10000
  int align_window_frames = 200;   ///< frames per latency-minimum window, 8 .. 100000
  std::uint8_t crank_channel = 0;  ///< EdgeEvent::channel for entries with channel bit 0
  std::uint8_t cam_channel = 1;    ///< EdgeEvent::channel for entries with channel bit 1
};

/// Validates the config; returns nullptr when valid, else what is wrong.
[[nodiscard]] const char* validate(const CanEncoderConfig& cfg) noexcept;

namespace can_encoder {

inline constexpr std::uint32_t kTickBits = 30;
inline constexpr std::uint32_t kTickMask = (1u << kTickBits) - 1u;
inline constexpr std::uint8_t kFlagRestart = 1u << 6;
inline constexpr std::uint8_t kFlagOverflow = 1u << 7;
inline constexpr int kMaxEntriesFd = 15;
inline constexpr int kMaxEntriesClassic = 1;

/// Max entries per frame for this config.
[[nodiscard]] constexpr int max_entries(const CanEncoderConfig& cfg) noexcept {
  return cfg.fd ? kMaxEntriesFd : kMaxEntriesClassic;
}

/// One entry as carried on the wire.
struct Entry {
  std::uint32_t ticks = 0;  ///< time mod 2^30 (ticks)
  std::uint8_t level = 0;
  bool cam = false;
};

/// Frame contents after decoding.
struct FrameView {
  std::uint8_t seq = 0;
  std::uint8_t flags = 0;
  int n = 0;
  std::array<Entry, kMaxEntriesFd> entries{};
};

/// Valid CAN FD payload length >= len (0..8, 12, 16, 20, 24, 32, 48, 64).
[[nodiscard]] std::uint8_t fd_length(std::size_t len) noexcept;

/// Encodes up to max_entries(cfg) edges (times in ns on the encoder's clock, >= 0) into `out`; id, flags,
/// length and data are set, out.t_ns = time of the last edge. Edges whose channel is neither crank nor cam
/// channel are sent as crank. Returns the number of edges consumed (0 when n == 0: then an empty frame is
/// produced).
std::size_t encode_frame(const EdgeEvent* edges, std::size_t n, std::uint8_t seq, std::uint8_t flags,
                         const CanEncoderConfig& cfg, CanFrame& out) noexcept;

/// Decodes the payload of an encoder frame. Returns nullptr on success, else what was expected (length too
/// short for n, n too large for the frame type, non-zero reserved bits). Does not check the id.
[[nodiscard]] const char* decode_frame(const CanFrame& frame, const CanEncoderConfig& cfg,
                                       FrameView& out) noexcept;

/// Turns a stream of edges into encoder frames, like the encoder interface does: a frame is closed when full
/// or when its first edge is older than max_latency_ns at the time of the next edge (or at flush()).
class Batcher {
 public:
  Batcher(const CanEncoderConfig& cfg, std::int64_t max_latency_ns) noexcept
      : cfg_(cfg), max_latency_ns_(max_latency_ns) {}
  /// Adds an edge; returns true when `out` holds a completed frame (which does NOT contain `edge` unless
  /// the frame was closed by becoming full with it).
  bool push(const EdgeEvent& edge, CanFrame& out) noexcept;
  /// Emits the pending frame, if any.
  bool flush(CanFrame& out) noexcept;
  [[nodiscard]] std::uint64_t frames() const noexcept { return frames_; }

 private:
  bool emit(CanFrame& out) noexcept;
  CanEncoderConfig cfg_;
  std::int64_t max_latency_ns_;
  std::array<EdgeEvent, kMaxEntriesFd> pending_{};
  int n_ = 0;
  std::uint8_t seq_ = 0;
  std::uint64_t frames_ = 0;
};

}  // namespace can_encoder

/// Counters of the encoder decoding (in addition to SourceStats).
struct CanEncoderStats {
  std::uint64_t frames = 0;            ///< encoder frames decoded
  std::uint64_t other_frames = 0;      ///< frames with another id, ignored
  std::uint64_t bad_frames = 0;        ///< malformed encoder frames, skipped
  std::uint64_t lost_frames = 0;       ///< frames missing according to the sequence counter
  std::uint64_t sequence_errors = 0;   ///< times a gap in the sequence counter was seen
  std::uint64_t duplicate_frames = 0;  ///< same sequence number twice in a row (dropped)
  std::uint64_t overflow_flags = 0;    ///< frames with the encoder's overflow flag
  std::uint64_t restarts = 0;          ///< frames with the restart flag (unwrap restarted)
  std::uint64_t backwards = 0;         ///< entries earlier than the previous one (dropped)
  std::uint64_t long_pauses = 0;       ///< unwraps resolved from receive times (pause > half a wrap)
  double align_offset_ns = 0.0;  ///< align_to_receive_time: current encoder -> receive clock offset (ns)
  double align_rate_ppm = 0.0;   ///< align_to_receive_time: current slew rate (ppm)
  double align_drift_ppm = 0.0;  ///< align_to_receive_time: estimated encoder-vs-host clock drift (ppm)
  double align_error_ns = 0.0;   ///< align_to_receive_time: offset error at the last window end (ns)
};

/// EdgeSource reading encoder frames from a CanSource (SocketCAN live, or a candump log in replay).
/// Frames with other ids are skipped. Lost frames (sequence gaps) are counted in stats().dropped and
/// encoder_stats().lost_frames; the crank decoder sees the missing edges as lost teeth or a sync loss.
class CanEncoderEdgeSource final : public EdgeSource {
 public:
  /// `can` must outlive this source.
  CanEncoderEdgeSource(CanSource& can, const CanEncoderConfig& cfg);
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }

  SourceStatus next(EdgeEvent& out) noexcept override;
  [[nodiscard]] const SourceStats& stats() const noexcept override { return stats_; }
  [[nodiscard]] const CanEncoderStats& encoder_stats() const noexcept { return enc_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string last_error() const override;
  void request_stop() noexcept override { can_.request_stop(); }

 private:
  void accept(const CanFrame& frame) noexcept;
  void align(std::int64_t rx_ns) noexcept;

  CanSource& can_;
  CanEncoderConfig cfg_;
  std::string error_;
  can_encoder::FrameView view_{};
  std::array<EdgeEvent, can_encoder::kMaxEntriesFd> out_{};
  int out_n_ = 0, out_i_ = 0;
  bool have_seq_ = false;
  std::uint8_t last_seq_ = 0;
  bool have_time_ = false;
  std::int64_t last_ticks_ = 0;  ///< unwrapped ticks of the last entry
  std::uint32_t last_raw_ = 0;   ///< its 30-bit wire value
  std::int64_t last_rx_ns_ = 0;  ///< receive time of the frame holding the last entry
  // Receive-time alignment (align_to_receive_time).
  bool aligned_ = false;
  std::int64_t offset_base_ns_ =
      0;                          ///< encoder time -> receive clock: integer part set at the first frame (ns)
  double offset_ns_ = 0.0;        ///< ... plus the slewed part (ns)
  double rate_ = 0.0;             ///< d(offset)/d(encoder time), |rate_| <= max_slew_ppm
  double drift_ = 0.0;            ///< estimated slope of the latency envelope (encoder vs host clock)
  std::int64_t slew_ref_ns_ = 0;  ///< encoder time up to which the offset has been integrated
  std::int64_t win_start_ns_ = 0;  ///< encoder time at the window's start
  double win_min_ = 0.0;           ///< lower envelope (detrended) of the current window (ns)
  int win_frames_ = 0;
  bool have_floor_ = false;
  double floor_prev_ = 0.0, mid_prev_ = 0.0;  ///< previous window's envelope value and time (ns)
  SourceStats stats_;
  CanEncoderStats enc_;
  std::array<char, 160> bad_msg_{};  ///< last bad frame, fixed buffer (no allocation in next())
};

}  // namespace torqued
