#include "time_sanity.hpp"

#include <cinttypes>
#include <cstdio>

namespace torqued {
namespace {
constexpr std::size_t kMaxMessages = 20;

/// A magnitude of nanoseconds with its sign as seconds with 9 decimals ("-0.000500000").
std::string seconds(bool negative, std::uint64_t a) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "", a / 1'000'000'000u,
                a % 1'000'000'000u);
  return buf;
}
std::string seconds(std::int64_t ns) {
  return seconds(ns < 0, ns < 0 ? 0 - static_cast<std::uint64_t>(ns) : static_cast<std::uint64_t>(ns));
}
/// t − base as seconds, exact for any two times: the distance taken unsigned (two times of opposite sign can
/// be more than INT64_MAX apart).
std::string seconds_between(std::int64_t t, std::int64_t base) {
  const auto ut = static_cast<std::uint64_t>(t), ub = static_cast<std::uint64_t>(base);
  return t >= base ? seconds(false, ut - ub) : seconds(true, ub - ut);
}
}  // namespace

std::string describe_time_drop(const TimeDrop& d, const std::string& path) {
  std::string s = path + ":" + std::to_string(d.line) + ": ";
  if (d.backwards)
    return s + "time goes backwards (" + seconds(d.t_ns) + " s after " + seconds(d.base_ns) + " s): dropped";
  return s + "time " + seconds(d.t_ns) + " s is " + seconds_between(d.t_ns, d.base_ns) +
         " s off the time base (" + seconds(d.base_ns) +
         " s) and too few records follow it in step (inputs.max_time_jump_s, inputs.time_rebase_records): "
         "dropped as an outlier";
}

void note_time_drop(const TimeDrop& d, const std::string& path, SourceStats& stats,
                    std::vector<std::string>& messages, std::string& error) noexcept {
  ++stats.bad_lines;
  ++stats.time_outliers;
  if (messages.size() >= kMaxMessages) return;
  try {
    messages.push_back(describe_time_drop(d, path));
    error = messages.back();
  } catch (...) {  // out of memory while formatting: the counts are in stats
  }
}

}  // namespace torqued
