#include "sample_recorder.hpp"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>

#include "topic_format.hpp"

namespace torqued::dds {
namespace {
constexpr std::size_t kFlushBytes = 64 * 1024;
/// A buffer holds < kFlushBytes after each row, plus room for the longest row (csv_row_max_chars, < 2 KiB;
/// checked when a file is opened) or the header.
constexpr std::size_t kRowRoom = 4096;
constexpr std::size_t kBufBytes = kFlushBytes + kRowRoom;

int file_index(const AnySample& s) {
  switch (s.topic) {
    case Topic::kEngineTorque:
      return s.u.engine.kind == torque_KIND_CYCLE ? 0 : 1;
    case Topic::kEstimatorTorque:
      return 2;
    case Topic::kCylinderTorque:
      return 3;
    case Topic::kCrankState:
      return 4;
    case Topic::kDaemonStatus:
      return 5;
  }
  return 5;
}
std::int64_t coarse_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC_COARSE, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
}  // namespace

SampleRecorder::SampleRecorder(std::string dir, bool record_status)
    : dir_(std::move(dir)), record_status_(record_status) {
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec) error_ = "cannot create record directory '" + dir_ + "': " + ec.message();
}

SampleRecorder::~SampleRecorder() {
  flush();
  for (auto& f : files_)
    if (f.fd >= 0) ::close(f.fd);
}

SampleRecorder::File* SampleRecorder::file_for(const AnySample& s) {
  if (!ok()) [[unlikely]] {
    if (write_failed_.load(std::memory_order_relaxed)) dropped_.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
  }
  if (s.topic == Topic::kDaemonStatus && !record_status_) return nullptr;
  const int i = file_index(s);
  File& f = files_[static_cast<std::size_t>(i)];
  if (f.fd >= 0) [[likely]]
    return &f;
  return open_file(s, i);
}

SampleRecorder::File* SampleRecorder::open_file(const AnySample& s, int i) {
  File& f = files_[static_cast<std::size_t>(i)];
  const std::string path = dir_ + "/" + kFileNames[static_cast<std::size_t>(i)];
  const std::string header = s.visit([](const auto& v) { return csv_header<std::decay_t<decltype(v)>>(); });
  const std::size_t row_max =
      s.visit([](const auto& v) { return csv_row_max_chars<std::decay_t<decltype(v)>>(); });
  if (header.size() > kRowRoom || row_max > kRowRoom) {  // a topic grew: raise kRowRoom
    error_ = "CSV row of " + path + " longer than the recorder's row room";
    return nullptr;
  }
  f.fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (f.fd < 0) {  // a write error like any other (a read-only or full file system): flagged, row counted
    fail(i, "open", errno);
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
  }
  f.buf = std::make_unique<char[]>(kBufBytes);
  std::memcpy(f.buf.get(), header.data(), header.size());
  f.used = header.size();
  return &f;
}

void SampleRecorder::record(const AnySample& s) {
  File* f = file_for(s);
  if (!f) return;
  char* const p = f->buf.get() + f->used;
  f->used =
      static_cast<std::size_t>(s.visit([p](const auto& v) { return write_csv_row(p, v); }) - f->buf.get());
  after_row(f, s.topic == Topic::kDaemonStatus);
}

void SampleRecorder::record(const AnySample& s, std::uint16_t engine_id) {
  File* f = file_for(s);
  if (!f) return;
  char* const p = f->buf.get() + f->used;
  f->used = static_cast<std::size_t>(s.visit([p, engine_id](const auto& v) {
    auto c = v;  // one topic struct, not the whole AnySample
    c.engine_id = engine_id;
    return write_csv_row(p, c);
  }) - f->buf.get());
  after_row(f, s.topic == Topic::kDaemonStatus);
}

void SampleRecorder::after_row(File* f, bool status) {
  ++rows_;
  if (f->used >= kFlushBytes) write_out(static_cast<int>(f - files_.data()));
  // Timed flush: at each DaemonStatus row (once per status period) and every kFlushPeriodNs while rows flow.
  if (status || rows_ % kClockCheckRows == 0) {
    const std::int64_t now = coarse_now_ns();
    if (status || now - last_flush_ns_ >= kFlushPeriodNs) {
      last_flush_ns_ = now;
      flush(false);
    }
  }
}

void SampleRecorder::write_out(int i) {
  File& f = files_[static_cast<std::size_t>(i)];
  if (f.fd < 0 || f.used == 0) return;
  if (write_failed_.load(std::memory_order_relaxed)) {  // recording stopped at the first error
    drop_rows(f, f.buf.get());
    f.used = 0;
    return;
  }
  const char* p = f.buf.get();
  std::size_t left = f.used;
  while (left > 0) {
    const ssize_t n = ::write(f.fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : ENOSPC;
      // Cut the file back to its last complete row (the buffer holds complete rows; a write may stop inside
      // one), count the rows lost with the buffer, stop recording.
      const char* b = f.buf.get();
      const auto* nl = static_cast<const char*>(memrchr(b, '\n', static_cast<std::size_t>(p - b)));
      const std::uint64_t keep = f.written + (nl ? static_cast<std::uint64_t>(nl - b + 1) : 0);
      if (::ftruncate(f.fd, static_cast<off_t>(keep)) == 0) ::lseek(f.fd, static_cast<off_t>(keep), SEEK_SET);
      if (nl) f.written = keep;  // the header (if it was in this buffer) is on disk
      drop_rows(f, nl ? nl + 1 : b);
      fail(i, "write", err);
      f.used = 0;
      return;
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  f.written += f.used;
  f.used = 0;
}

void SampleRecorder::drop_rows(const File& f, const char* from) {
  const char* end = f.buf.get() + f.used;
  std::uint64_t n = static_cast<std::uint64_t>(std::count(from, end, '\n'));
  if (f.written == 0 && from == f.buf.get() && n > 0) --n;  // the header line, not a row
  dropped_.fetch_add(n, std::memory_order_relaxed);
}

void SampleRecorder::fail(int i, const char* what, int err) {
  if (error_.empty())
    error_ = std::string(what) + " error in " + dir_ + "/" + kFileNames[static_cast<std::size_t>(i)] + ": " +
             std::strerror(err) + " (recording stopped; rows from here on are not recorded)";
  write_failed_.store(true, std::memory_order_release);
}

std::vector<std::string> SampleRecorder::flush_sync_within(double timeout_s) {
  // Shared with the fsync threads, which may outlive this call (and this recorder) on a stuck disk.
  struct Pending {
    std::mutex m;
    std::condition_variable cv;
    std::array<int, kFiles> state{};  ///< 0 not started / no file, 1 running, 2 done
    std::array<int, kFiles> err{};
  };
  auto p = std::make_shared<Pending>();
  std::vector<std::thread> threads;
  for (int i = 0; i < kFiles; ++i) {
    write_out(i);
    const int fd = files_[static_cast<std::size_t>(i)].fd;
    if (fd < 0 || write_failed_.load(std::memory_order_relaxed)) continue;
    p->state[static_cast<std::size_t>(i)] = 1;
    threads.emplace_back([p, fd, i] {
      const int e = ::fsync(fd) != 0 ? errno : 0;
      const std::lock_guard<std::mutex> lk(p->m);
      p->state[static_cast<std::size_t>(i)] = 2;
      p->err[static_cast<std::size_t>(i)] = e;
      p->cv.notify_all();
    });
  }
  std::unique_lock<std::mutex> lk(p->m);
  const auto all_done = [&p] {
    return std::none_of(p->state.begin(), p->state.end(), [](int s) { return s == 1; });
  };
  (void)p->cv.wait_for(lk, std::chrono::duration<double>(std::max(timeout_s, 0.0)), all_done);
  std::vector<std::string> pending;
  for (int i = 0; i < kFiles; ++i) {
    const auto ii = static_cast<std::size_t>(i);
    if (p->state[ii] == 1) pending.emplace_back(kFileNames[ii]);
    if (p->state[ii] == 2 && p->err[ii] != 0) fail(i, "fsync", p->err[ii]);
  }
  lk.unlock();
  for (auto& t : threads) t.detach();  // done ones have ended or are ending; stuck ones finish on their own
  return pending;
}

void SampleRecorder::flush(bool sync) {
  for (int i = 0; i < kFiles; ++i) {
    write_out(i);
    const int fd = files_[static_cast<std::size_t>(i)].fd;
    if (sync && fd >= 0 && !write_failed_.load(std::memory_order_relaxed) && ::fsync(fd) != 0)
      fail(i, "fsync", errno);
  }
}

}  // namespace torqued::dds
