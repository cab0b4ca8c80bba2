#pragma once
// Edge → publish latency of the samples, on the publisher thread: 1 µs buckets up to 10 ms (fixed size, no
// allocation; later samples land in the last bucket and are counted there, the maximum is kept exactly).
// Percentiles over each status period (period_*) and over the whole run (run_*), published in DaemonStatus.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>

namespace torqued {

struct LatencyFigures {
  std::int64_t p50_ns = -1, p99_ns = -1, max_ns = 0;
  std::uint64_t n = 0;
};

class LatencyHistogram {
 public:
  static constexpr int kBuckets = 10000;  ///< 1 µs each; bucket kBuckets holds everything ≥ 10 ms

  LatencyHistogram() : period_(new std::uint32_t[kBuckets + 1]()), run_(new std::uint64_t[kBuckets + 1]()) {}

  void note(std::int64_t lat_ns) noexcept {
    const std::int64_t us = lat_ns / 1000;
    const auto b = static_cast<std::size_t>(us < 0 ? 0 : (us >= kBuckets ? kBuckets : us));
    ++period_[b];
    ++run_[b];
    ++n_period_;
    ++n_run_;
    if (lat_ns > max_period_) max_period_ = lat_ns;
    if (lat_ns > max_run_) max_run_ = lat_ns;
  }
  /// Figures of the period since the last call, then starts a new period.
  LatencyFigures take_period() noexcept {
    LatencyFigures f = figures(period_.get(), n_period_, max_period_);
    for (int b = 0; b <= kBuckets; ++b) period_[static_cast<std::size_t>(b)] = 0;
    n_period_ = 0;
    max_period_ = 0;
    return f;
  }
  [[nodiscard]] LatencyFigures run() const noexcept { return figures(run_.get(), n_run_, max_run_); }
  [[nodiscard]] std::uint64_t period_count() const noexcept { return n_period_; }

 private:
  template <class C>
  static LatencyFigures figures(const C* h, std::uint64_t n, std::int64_t max_ns) noexcept {
    LatencyFigures f;
    f.n = n;
    f.max_ns = max_ns;
    if (n == 0) return f;
    const std::uint64_t k50 = (n + 1) / 2, k99 = n - n / 100;
    std::uint64_t acc = 0;
    for (int b = 0; b <= kBuckets; ++b) {
      acc += h[static_cast<std::size_t>(b)];
      // The overflow bucket reports the exact maximum (an upper bound), so no percentile is capped at 10 ms.
      const std::int64_t v = b == kBuckets ? max_ns : b * 1000LL;
      if (f.p50_ns < 0 && acc >= k50) f.p50_ns = v;
      if (f.p99_ns < 0 && acc >= k99) f.p99_ns = v;
    }
    return f;
  }

  std::unique_ptr<std::uint32_t[]> period_;
  std::unique_ptr<std::uint64_t[]> run_;
  std::uint64_t n_period_ = 0, n_run_ = 0;
  std::int64_t max_period_ = 0, max_run_ = 0;
};

}  // namespace torqued
