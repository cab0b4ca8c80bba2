#include "replay_merger.hpp"

namespace torqued {

ReplayMerger::ReplayMerger(EdgeSource* edges, CanSource* can, std::int64_t can_time_offset_ns) noexcept
    : edges_(edges), can_(can), can_offset_ns_(can_time_offset_ns) {
  edge_done_ = edges_ == nullptr;
  can_done_ = can_ == nullptr;
}

SourceStatus ReplayMerger::fill_edge() noexcept {
  if (edge_ready_ || edge_done_) return SourceStatus::kOk;
  const SourceStatus s = edges_->next(edge_);
  if (s == SourceStatus::kOk) {
    if (edge_.t_ns < last_edge_t_) ++out_of_order_;
    last_edge_t_ = edge_.t_ns;
    edge_ready_ = true;
  } else if (s == SourceStatus::kEnd || s == SourceStatus::kError) {
    edge_done_ = true;
  }
  return s;
}

SourceStatus ReplayMerger::fill_can() noexcept {
  if (can_ready_ || can_done_) return SourceStatus::kOk;
  const SourceStatus s = can_->next(frame_);
  if (s == SourceStatus::kOk) {
    frame_.t_ns += can_offset_ns_;
    if (frame_.t_ns < last_can_t_) ++out_of_order_;
    last_can_t_ = frame_.t_ns;
    can_ready_ = true;
  } else if (s == SourceStatus::kEnd || s == SourceStatus::kError) {
    can_done_ = true;
  }
  return s;
}

SourceStatus ReplayMerger::next(Item& out) noexcept {
  const SourceStatus se = fill_edge();
  const SourceStatus sc = fill_can();
  // Report a failing source once; the other one keeps going.
  if (se == SourceStatus::kError || sc == SourceStatus::kError) return SourceStatus::kError;
  // A live source with nothing yet: we cannot know the order, so wait (only while it is not finished).
  if (se == SourceStatus::kWouldBlock || sc == SourceStatus::kWouldBlock) return SourceStatus::kWouldBlock;
  if (!edge_ready_ && !can_ready_) return SourceStatus::kEnd;
  const bool take_edge = edge_ready_ && (!can_ready_ || edge_.t_ns <= frame_.t_ns);
  if (take_edge) {
    out.kind = Kind::kEdge;
    out.edge = edge_;
    edge_ready_ = false;
    ++edges_out_;
  } else {
    out.kind = Kind::kCan;
    out.frame = frame_;
    can_ready_ = false;
    ++frames_out_;
  }
  return SourceStatus::kOk;
}

}  // namespace torqued
