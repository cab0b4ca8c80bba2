#include "sample_recorder.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

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
    case Topic::kEngineTorque: return s.u.engine.kind == torque_KIND_CYCLE ? 0 : 1;
    case Topic::kEstimatorTorque: return 2;
    case Topic::kCylinderTorque: return 3;
    case Topic::kCrankState: return 4;
    case Topic::kDaemonStatus: return 5;
  }
  return 5;
}
}  // namespace

SampleRecorder::SampleRecorder(std::string dir, bool record_status) : dir_(std::move(dir)), record_status_(record_status) {
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
  if (!ok()) [[unlikely]]
    return nullptr;
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
  const std::size_t row_max = s.visit([](const auto& v) { return csv_row_max_chars<std::decay_t<decltype(v)>>(); });
  if (header.size() > kRowRoom || row_max > kRowRoom) {  // a topic grew: raise kRowRoom
    error_ = "CSV row of " + path + " longer than the recorder's row room";
    return nullptr;
  }
  f.fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (f.fd < 0) {
    error_ = "cannot write '" + path + "': " + std::strerror(errno);
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
  f->used = static_cast<std::size_t>(s.visit([p](const auto& v) { return write_csv_row(p, v); }) - f->buf.get());
  ++rows_;
  if (f->used >= kFlushBytes) write_out(static_cast<int>(f - files_.data()));
}

void SampleRecorder::record(const AnySample& s, std::uint16_t engine_id) {
  File* f = file_for(s);
  if (!f) return;
  char* const p = f->buf.get() + f->used;
  f->used = static_cast<std::size_t>(s.visit([p, engine_id](const auto& v) {
                                       auto c = v;  // one topic struct, not the whole AnySample
                                       c.engine_id = engine_id;
                                       return write_csv_row(p, c);
                                     }) -
                                     f->buf.get());
  ++rows_;
  if (f->used >= kFlushBytes) write_out(static_cast<int>(f - files_.data()));
}

void SampleRecorder::write_out(int i) {
  File& f = files_[static_cast<std::size_t>(i)];
  if (f.fd < 0 || f.used == 0) return;
  const char* p = f.buf.get();
  std::size_t left = f.used;
  while (left > 0) {
    const ssize_t n = ::write(f.fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (error_.empty())
        error_ = std::string("write error in ") + kFileNames[static_cast<std::size_t>(i)] + ": " +
                 (n < 0 ? std::strerror(errno) : "no progress");
      break;
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  f.used = 0;
}

void SampleRecorder::flush(bool sync) {
  for (int i = 0; i < kFiles; ++i) {
    write_out(i);
    if (sync && files_[static_cast<std::size_t>(i)].fd >= 0) ::fsync(files_[static_cast<std::size_t>(i)].fd);
  }
}

}  // namespace torqued::dds
