#pragma once
// Final consumer of samples: records to CSV and/or writes to DDS. NOT real-time (file writes, DDS): used by
// the publisher thread and by the single-threaded fast replay.
#include "dds_publisher.hpp"
#include "sample_recorder.hpp"
#include "sample_sink.hpp"

namespace torqued {

class OutputFanout final : public SampleSink {
 public:
  OutputFanout(dds::SampleRecorder* recorder, DdsPublisher* publisher, std::uint16_t engine_id = 0) noexcept
      : rec_(recorder), pub_(publisher), engine_id_(engine_id) {}
  void emit(const dds::AnySample& s) noexcept override {
    try {
      if (!pub_) {  // recorder only (fast replay --no-dds): it writes engine_id_, no copy of the sample
        if (rec_) rec_->record(s, engine_id_);
        return;
      }
      dds::AnySample copy = s;
      copy.visit([this](auto& v) { v.engine_id = engine_id_; });
      (void)pub_->write(copy);  // stamps engine_id + publish time first, so the CSV shows them too
      if (rec_) rec_->record(copy);
    } catch (...) {
      ++record_errors_;
    }
  }
  /// Hands the recorder's buffers to the files (no fsync): the fast replay's timed loop ends with it.
  void flush() noexcept override {
    try {
      if (rec_) rec_->flush(false);
    } catch (...) {
      ++record_errors_;
    }
  }
  [[nodiscard]] std::uint64_t record_errors() const noexcept { return record_errors_; }

 private:
  dds::SampleRecorder* rec_;
  DdsPublisher* pub_;
  std::uint16_t engine_id_;
  std::uint64_t record_errors_ = 0;
};

}  // namespace torqued
