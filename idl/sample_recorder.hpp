#pragma once
// Writes samples to CSV files in a directory, one file per topic (EngineTorque split by kind):
//   engine_cycle.csv, engine_segment.csv, estimator_torque.csv, cylinder_torque.csv, crank_state.csv,
//   daemon_status.csv
// Columns: topic_format.hpp (first column t_ns = source timestamp on the edge clock), the format torque-eval
// reads. Buffered: each file has its own buffer, rows are formatted straight into it (write_csv_row) and it
// goes to the file with one write(2) per 64 KiB (page-cache copies were fastest at this size on this VM:
// larger chunks fall out of the cache) and on flush()/destruction. Not real-time: used by the publisher
// thread / fast replay / torque-echo. A file is created with its header on its first sample.
#include <array>
#include <cstdint>
#include <memory>
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
  /// Same, with `engine_id` written instead of the sample's own (the fast replay's fan-out: no sample copy).
  void record(const AnySample& s, std::uint16_t engine_id);
  /// Writes the buffers to the files; with sync also fsync()s them.
  void flush(bool sync = false);
  [[nodiscard]] std::uint64_t rows() const noexcept { return rows_; }

  static constexpr int kFiles = 6;
  static constexpr std::array<const char*, kFiles> kFileNames = {
      "engine_cycle.csv", "engine_segment.csv", "estimator_torque.csv", "cylinder_torque.csv", "crank_state.csv",
      "daemon_status.csv"};

 private:
  struct File {
    int fd = -1;
    std::unique_ptr<char[]> buf;  ///< kBufBytes
    std::size_t used = 0;
  };
  /// The file of sample s, opened (with its header) on first use; nullptr if not recorded or on error.
  File* file_for(const AnySample& s);
  File* open_file(const AnySample& s, int i);  ///< first sample of file i: open it, header into its buffer
  void write_out(int i);
  std::string dir_;
  bool record_status_;
  std::array<File, kFiles> files_{};
  std::string error_;
  std::uint64_t rows_ = 0;
};

}  // namespace torqued::dds
