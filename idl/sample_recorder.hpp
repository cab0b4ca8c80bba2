#pragma once
// Writes samples to CSV files in a directory, one file per topic (EngineTorque split by kind):
//   engine_cycle.csv, engine_segment.csv, estimator_torque.csv, cylinder_torque.csv, crank_state.csv,
//   daemon_status.csv
// Columns: topic_format.hpp (first column t_ns = source timestamp on the edge clock), the format torque-eval
// reads. Buffered: each file has its own buffer, rows are formatted straight into it (write_csv_row) and it
// goes to the file with one write(2) per 64 KiB (page-cache copies were fastest at this size on this VM:
// larger chunks fall out of the cache), on flush()/destruction, and on a timer: every buffer is written when
// a DaemonStatus sample is recorded (each status period, 1 s by default) and when kFlushPeriodNs has passed
// since the last timed write (checked every kClockCheckRows rows). So a kill -9 loses at most the rows of the
// last max(0.25 s, status period) (1 s by default). Not real-time: used by the publisher thread / fast replay
// / torque-echo. A file is created with its header on its first sample. Write errors (a full disk, EIO, a
// file that cannot be opened: a read-only file system): the first one is kept (error()), write_failed() turns
// true at once (for another thread to report it: the supervisor polls it), the file it happened in is cut
// back to its last complete row, and recording stops (every later row is counted in rows_dropped()): a
// recording is always a prefix of complete rows. The caller goes on estimating and publishing.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sample.hpp"

namespace torqued::dds {

class SampleRecorder {
 public:
  /// Creates `dir` if needed. Check ok()/error().
  explicit SampleRecorder(std::string dir, bool record_status = true);
  ~SampleRecorder();
  SampleRecorder(const SampleRecorder&) = delete;
  SampleRecorder& operator=(const SampleRecorder&) = delete;

  /// False after a failed directory creation, open or write.
  [[nodiscard]] bool ok() const noexcept { return error_.empty(); }
  /// The first error. From another thread: read only after write_failed() returned true.
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  /// A write or fsync failed (thread-safe; the DaemonStatus / exit-code flag).
  [[nodiscard]] bool write_failed() const noexcept { return write_failed_.load(std::memory_order_acquire); }
  /// Rows not recorded because of a write error (thread-safe).
  [[nodiscard]] std::uint64_t rows_dropped() const noexcept {
    return dropped_.load(std::memory_order_relaxed);
  }
  void record(const AnySample& s);
  /// Same, with `engine_id` written instead of the sample's own (the fast replay's fan-out: no sample copy).
  void record(const AnySample& s, std::uint16_t engine_id);
  /// Writes the buffers to the files; with sync also fsync()s them.
  void flush(bool sync = false);
  /// At stop: writes the buffers, then fsync()s the files in parallel (one thread each) and waits at most
  /// timeout_s. Returns the names of the files whose fsync had not returned by then (their rows are written
  /// but not known to be on disk; the threads are left to finish on their own). A failed fsync counts as
  /// write_failed() as in flush(true). Not real-time.
  std::vector<std::string> flush_sync_within(double timeout_s);
  [[nodiscard]] std::uint64_t rows() const noexcept { return rows_; }

  static constexpr std::int64_t kFlushPeriodNs = 250'000'000;
  static constexpr std::uint32_t kClockCheckRows = 64;
  static constexpr int kFiles = 6;
  static constexpr std::array<const char*, kFiles> kFileNames = {
      "engine_cycle.csv",    "engine_segment.csv", "estimator_torque.csv",
      "cylinder_torque.csv", "crank_state.csv",    "daemon_status.csv"};

 private:
  struct File {
    int fd = -1;
    std::unique_ptr<char[]> buf;  ///< kBufBytes
    std::size_t used = 0;
    std::uint64_t written = 0;  ///< bytes in the file (always ends with a complete row)
  };
  /// The file of sample s, opened (with its header) on first use; nullptr if not recorded or on error.
  File* file_for(const AnySample& s);
  File* open_file(const AnySample& s, int i);  ///< first sample of file i: open it, header into its buffer
  void write_out(int i);
  void fail(int i, const char* what, int err);
  void drop_rows(const File& f, const char* from);  ///< counts the rows of f's buffer from `from` as dropped
  void after_row(File* f, bool status);
  std::string dir_;
  bool record_status_;
  std::array<File, kFiles> files_{};
  std::string error_;
  std::uint64_t rows_ = 0;
  std::int64_t last_flush_ns_ = 0;
  std::atomic<bool> write_failed_{false};
  std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace torqued::dds
