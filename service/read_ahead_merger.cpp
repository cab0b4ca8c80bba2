#include "read_ahead_merger.hpp"

#include "back_off.hpp"

namespace torqued {

std::string source_error_message(const EdgeSource* edges, const CanSource* can) noexcept {
  try {
    return (edges && !edges->last_error().empty()) ? edges->last_error()
           : can                                   ? can->last_error()
                                                   : "source error";
  } catch (...) {
    return {};
  }
}

ReadAheadMerger::ReadAheadMerger(EdgeSource* edges, CanSource* can, std::int64_t can_offset_ns,
                                 std::size_t capacity)
    : edges_(edges), can_(can), merger_(edges, can, can_offset_ns), ring_(capacity), thread_([this] {
        run();
      }) {}

ReadAheadMerger::~ReadAheadMerger() { stop(); }

SourceStatus ReadAheadMerger::next(ReplayMerger::Item& out) noexcept {
  if (ended_) return SourceStatus::kEnd;
  const Record* r = ring_.front();
  if (r == nullptr) {
    ++waits_;
    unsigned round = 0;
    while ((r = ring_.front()) == nullptr) back_off(round);
  }
  const SourceStatus st = r->status;
  out.kind = r->kind;  // only the half of the record in use: its other cache lines stay on the reader's core
  if (r->kind == ReplayMerger::Kind::kEdge)
    out.edge = r->edge;
  else
    out.frame = r->frame;
  frames_out_ = r->frames_out;
  source_drops_ = r->source_drops;
  ring_.pop_front();
  if (st == SourceStatus::kEnd) ended_ = true;
  return st;
}

void ReadAheadMerger::stop() noexcept {
  if (joined_) return;
  quit_.store(true, std::memory_order_release);
  thread_.join();
  joined_ = true;
}

void ReadAheadMerger::run() noexcept {
  ReplayMerger::Item item;
  for (;;) {
    const SourceStatus status = merger_.next(item);
    if (status == SourceStatus::kError && first_error_.empty())
      first_error_ = source_error_message(edges_, can_);
    Record* rec = ring_.claim();
    if (rec == nullptr) {  // wait until the replay has taken half of it: fewer, longer turns of this thread
      do {
        if (quit_.load(std::memory_order_acquire)) return;
        rest();
      } while (ring_.size() > ring_.capacity() / 2);
      rec = ring_.claim();  // not null: only the replay takes records
    }
    rec->status = status;
    rec->kind = item.kind;
    rec->frames_out = merger_.frames_out();
    rec->source_drops = (edges_ ? edges_->stats().bad_lines + edges_->stats().dropped : 0) +
                        (can_ ? can_->stats().bad_lines + can_->stats().dropped : 0);
    if (status == SourceStatus::kOk) {
      if (item.kind == ReplayMerger::Kind::kEdge)
        rec->edge = item.edge;
      else
        rec->frame = item.frame;
    }
    ring_.publish();
    if (status == SourceStatus::kEnd || quit_.load(std::memory_order_acquire)) return;
  }
}

}  // namespace torqued
