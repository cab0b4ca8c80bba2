#pragma once
// Merges an edge source and a CAN source into one stream ordered by time, for the single-threaded,
// deterministic fast replay. Ties: edges first (stable, so output is byte-identical run to run).
// CAN times are shifted by can_time_offset_ns (config inputs.can.time_offset_s) onto the edge clock.
// next() is real-time safe when the sources are (file sources are).
#include <cstdint>
#include <limits>

#include "records.hpp"
#include "source.hpp"

namespace torqued {

class ReplayMerger {
 public:
  enum class Kind : std::uint8_t { kEdge = 0, kCan = 1 };
  struct Item {
    Kind kind = Kind::kEdge;
    EdgeEvent edge;  ///< valid when kind == kEdge
    CanFrame frame;  ///< valid when kind == kCan (t_ns already shifted onto the edge clock)
    [[nodiscard]] std::int64_t t_ns() const noexcept { return kind == Kind::kEdge ? edge.t_ns : frame.t_ns; }
  };

  /// Either source may be null. Sources must outlive the merger.
  ReplayMerger(EdgeSource* edges, CanSource* can, std::int64_t can_time_offset_ns = 0) noexcept;

  /// kOk with the earliest pending record; kEnd when both sources ended; kError once when a source fails
  /// (merging then goes on with the other source); kWouldBlock passed through from a live source.
  [[nodiscard]] SourceStatus next(Item& out) noexcept;

  [[nodiscard]] std::uint64_t edges_out() const noexcept { return edges_out_; }
  [[nodiscard]] std::uint64_t frames_out() const noexcept { return frames_out_; }
  /// Records whose time went backwards relative to the previous one from the same source (still delivered).
  [[nodiscard]] std::uint64_t out_of_order() const noexcept { return out_of_order_; }

 private:
  SourceStatus fill_edge() noexcept;
  SourceStatus fill_can() noexcept;

  EdgeSource* edges_;
  CanSource* can_;
  std::int64_t can_offset_ns_;
  EdgeEvent edge_{};
  CanFrame frame_{};
  bool edge_ready_ = false, can_ready_ = false;
  bool edge_done_ = false, can_done_ = false;
  std::int64_t last_edge_t_ = std::numeric_limits<std::int64_t>::min(),
               last_can_t_ = std::numeric_limits<std::int64_t>::min();
  std::uint64_t edges_out_ = 0, frames_out_ = 0, out_of_order_ = 0;
};

}  // namespace torqued
