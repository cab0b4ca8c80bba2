#include "sample_recorder.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "topic_format.hpp"

namespace torqued::dds {
namespace {
constexpr std::size_t kFlushBytes = 64 * 1024;

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
  for (auto* f : files_)
    if (f) std::fclose(f);
}

void SampleRecorder::record(const AnySample& s) {
  if (!ok()) return;
  if (s.topic == Topic::kDaemonStatus && !record_status_) return;
  const int i = file_index(s);
  if (!files_[i]) {
    const std::string path = dir_ + "/" + kFileNames[i];
    files_[i] = std::fopen(path.c_str(), "w");
    if (!files_[i]) {
      error_ = "cannot write '" + path + "': " + std::strerror(errno);
      return;
    }
    buf_[i] = s.visit([](const auto& v) { return csv_header<std::decay_t<decltype(v)>>(); });
  }
  s.visit([&](const auto& v) { append_csv_row(buf_[i], v); });
  ++rows_;
  if (buf_[i].size() >= kFlushBytes) write_out(i);
}

void SampleRecorder::write_out(int i) {
  if (!files_[i] || buf_[i].empty()) return;
  if (std::fwrite(buf_[i].data(), 1, buf_[i].size(), files_[i]) != buf_[i].size() && error_.empty())
    error_ = std::string("write error in ") + kFileNames[i] + ": " + std::strerror(errno);
  buf_[i].clear();
}

void SampleRecorder::flush(bool sync) {
  for (int i = 0; i < kFiles; ++i) {
    write_out(i);
    if (files_[i]) {
      std::fflush(files_[i]);
      if (sync) ::fsync(fileno(files_[i]));
    }
  }
}

}  // namespace torqued::dds
