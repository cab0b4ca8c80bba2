#pragma once
// Writes samples to CSV files in a directory, one file per topic (EngineTorque split by kind):
//   engine_cycle.csv, engine_segment.csv, estimator_torque.csv, cylinder_torque.csv, crank_state.csv,
//   daemon_status.csv
// Columns: topic_format.hpp (first column t_ns = source timestamp on the edge clock), the format torque-eval
// reads. Buffered (flushes every 64 KiB and on flush()/destruction). Not real-time: used by the publisher
// thread / fast replay / torque-echo. A file is created with its header on its first sample.
#include <array>
#include <cstdio>
#include <string>

#include "sample.hpp"

namespace torqued::dds {

class SampleRecorder {
 public:
  /// Creates `dir` if needed. Check ok()/error().
  explicit SampleRecorder(std::string dir, bool record_status = true);
  ~SampleRecorder();
  SampleRecorder(const SampleRecorder&) = delete;
  SampleRecorder& operator=(const SampleRecorder&) = delete;

  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  void record(const AnySample& s);
  /// Writes buffers to the files and fflush()es them; with sync also fsync()s.
  void flush(bool sync = false);
  [[nodiscard]] std::uint64_t rows() const noexcept { return rows_; }

  static constexpr int kFiles = 6;
  static constexpr std::array<const char*, kFiles> kFileNames = {
      "engine_cycle.csv", "engine_segment.csv", "estimator_torque.csv", "cylinder_torque.csv", "crank_state.csv",
      "daemon_status.csv"};

 private:
  void write_out(int i);
  std::string dir_;
  bool record_status_;
  std::array<std::FILE*, kFiles> files_{};
  std::array<std::string, kFiles> buf_;
  std::string error_;
  std::uint64_t rows_ = 0;
};

}  // namespace torqued::dds
