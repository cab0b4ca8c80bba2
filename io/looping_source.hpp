#pragma once
// Endless paced replay of a recording (replay.loop, off by default; the Debian package's configuration turns
// it on so that the service keeps publishing the bundled demo). Wraps a file source: at its end the file is
// opened again and every later record is shifted by one loop period, so time keeps increasing for the rings,
// the decoder and the estimators. The period is the same for the edge and the CAN source (loop_period_ns), so
// both inputs stay aligned loop after loop. At each seam the crank angle jumps (the recording's last and
// first teeth are not neighbours): the decoder loses sync once per loop and finds it again within a
// revolution. next() is real-time safe except at a seam, where the file is reopened (allocates; once per
// recording length, in the source thread, which reads files anyway).
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "records.hpp"
#include "source.hpp"

namespace torqued {

/// One loop period (ns) for both inputs: from the earliest first record to the latest last record (CAN times
/// with the configured CAN time offset applied), plus the last edge gap so that the next loop's first edge
/// follows the last one as a tooth would. 0 when the edge input has fewer than two edges (nothing to loop).
/// Reads both inputs once to their end (load time).
[[nodiscard]] std::int64_t loop_period_ns(EdgeSource& edges, CanSource* can, std::int64_t can_offset_ns);

template <class Base, class Record>
class LoopingSource final : public Base {
 public:
  using Factory = std::function<std::unique_ptr<Base>()>;
  /// `open` makes a fresh source of the same file; `period_ns` > 0 from loop_period_ns().
  LoopingSource(Factory open, std::int64_t period_ns) : open_(std::move(open)), period_ns_(period_ns) {
    inner_ = open_();
  }

  [[nodiscard]] SourceStatus next(Record& out) noexcept override {
    if (!inner_) return SourceStatus::kError;
    SourceStatus st = inner_->next(out);
    if (st == SourceStatus::kEnd && records_this_loop_ > 0) {
      add(base_, inner_->stats());
      try {
        inner_ = open_();  // the seam (see the header comment): allocates
      } catch (...) {
        inner_.reset();
      }
      if (!inner_) return SourceStatus::kError;
      offset_ns_ += period_ns_;
      ++loops_;
      records_this_loop_ = 0;
      st = inner_->next(out);
    }
    if (st == SourceStatus::kOk) {
      out.t_ns += offset_ns_;
      ++records_this_loop_;
    }
    return st;
  }
  /// Counters over every loop so far.
  [[nodiscard]] const SourceStats& stats() const noexcept override {
    sum_ = base_;
    if (inner_) add(sum_, inner_->stats());
    return sum_;
  }
  [[nodiscard]] std::string describe() const override {
    return (inner_ ? inner_->describe() : std::string("(closed)")) + ", looped every " +
           std::to_string(static_cast<double>(period_ns_) * 1e-9) + " s";
  }
  [[nodiscard]] std::string last_error() const override {
    return inner_ ? inner_->last_error() : "reopen failed";
  }
  [[nodiscard]] std::vector<std::string> input_messages() const override {
    return inner_ ? inner_->input_messages() : std::vector<std::string>{};
  }
  void request_stop() noexcept override {
    if (inner_) inner_->request_stop();
  }
  [[nodiscard]] std::uint64_t loops() const noexcept { return loops_; }

 private:
  static void add(SourceStats& a, const SourceStats& b) noexcept {
    a.records += b.records;
    a.bad_lines += b.bad_lines;
    a.dropped += b.dropped;
    a.bytes += b.bytes;
    a.lines += b.lines;
    a.reopens += b.reopens;
  }
  Factory open_;
  std::unique_ptr<Base> inner_;
  std::int64_t period_ns_;
  std::int64_t offset_ns_ = 0;  ///< added to every record time: loops_ * period_ns_
  std::uint64_t loops_ = 0;
  std::uint64_t records_this_loop_ = 0;  ///< an empty file ends instead of reopening forever
  SourceStats base_{};                   ///< counters of the finished loops
  mutable SourceStats sum_{};
};

using LoopingEdgeSource = LoopingSource<EdgeSource, EdgeEvent>;
using LoopingCanSource = LoopingSource<CanSource, CanFrame>;

}  // namespace torqued
