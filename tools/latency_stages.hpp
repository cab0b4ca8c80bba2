#pragma once
// torque-latency's "tail's stages": edge -> dds_write of the CrankState samples at or above p99.9, split with
// the daemon's own stamps (`torqued --stage-trace FILE`, one CSV row per CrankState, joined on seq). See
// docs/daemon.md ("Latency: what bounds it").
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace torqued::tools {

/// One row of the daemon's --stage-trace file (CLOCK_REALTIME ns).
struct StageRow {
  std::uint64_t seq = 0;
  std::int64_t ingest = 0, angle = 0, pushed = 0, taken = 0, written = 0;
};

inline std::vector<StageRow> read_stage_trace(const std::string& path) {
  std::vector<StageRow> rows;
  FILE* f = std::fopen(path.c_str(), "r");
  if (!f) return rows;
  char line[256];
  while (std::fgets(line, sizeof line, f)) {
    StageRow r;
    unsigned long long seq = 0;
    long long a = 0, b = 0, c = 0, d = 0, e = 0;
    if (std::sscanf(line, "%llu,%lld,%lld,%lld,%lld,%lld", &seq, &a, &b, &c, &d, &e) != 6) continue;
    r.seq = seq;
    r.ingest = a;
    r.angle = b;
    r.pushed = c;
    r.taken = d;
    r.written = e;
    rows.push_back(r);
  }
  std::fclose(f);
  std::sort(rows.begin(), rows.end(), [](const StageRow& x, const StageRow& y) { return x.seq < y.seq; });
  return rows;
}

/// The tail's stages: edge -> dds_write split with the daemon's own stamps (--stage-trace), for the
/// CrankState samples at or above edge -> received p99.9 and, for comparison, all of them (p50). The stage
/// with the largest mean over the tail owns it.
inline void print_tail_stages(const std::vector<std::array<double, 3>>& split,
                              const std::vector<std::uint64_t>& split_seq, const std::string& trace_path) {
  const std::vector<StageRow> rows = read_stage_trace(trace_path);
  if (split.size() < 100 || rows.empty()) {
    std::printf("the tail's stages: no stage trace from the daemon (%zu rows in %s)\n", rows.size(),
                trace_path.c_str());
    return;
  }
  static constexpr const char* kNames[] = {"edge due -> angle thread takes it (wake-up)",
                                           "angle thread -> sample in the output ring",
                                           "output ring -> publisher takes it",
                                           "publisher takes -> dds_write",
                                           "dds_write -> received (DDS)",
                                           "  (dds_write call returned, from its start)"};
  constexpr std::size_t kStages = 6;
  std::vector<double> tot;
  tot.reserve(split.size());
  for (const auto& v : split) tot.push_back(v[0]);
  std::sort(tot.begin(), tot.end());
  const double cut = tot[static_cast<std::size_t>(0.999 * static_cast<double>(tot.size() - 1))];
  std::array<std::vector<double>, kStages> all, tail;
  std::size_t joined = 0;
  for (std::size_t i = 0; i < split.size(); ++i) {
    const auto it = std::lower_bound(rows.begin(), rows.end(), split_seq[i],
                                     [](const StageRow& r, std::uint64_t q) { return r.seq < q; });
    if (it == rows.end() || it->seq != split_seq[i] || it->angle == 0) continue;
    ++joined;
    // dds_write's stamp (publish_t_ns) is in the subscriber's sample: edge -> dds_write after ingest.
    auto us = [](std::int64_t d) { return static_cast<double>(d) * 1e-3; };
    const double to_write = split[i][1];
    const std::array<double, kStages> st{us(it->angle - it->ingest),
                                         us(it->pushed - it->angle),
                                         us(it->taken - it->pushed),
                                         to_write - us(it->taken - it->ingest),
                                         split[i][2],
                                         us(it->written - it->ingest) - to_write};
    for (std::size_t k = 0; k < kStages; ++k) {
      all[k].push_back(st[k]);
      if (split[i][0] >= cut) tail[k].push_back(st[k]);
    }
  }
  if (tail[0].empty()) {
    std::printf("the tail's stages: no tail sample found in the daemon's stage trace (%zu rows)\n",
                rows.size());
    return;
  }
  auto mean = [](const std::vector<double>& v) {
    double a = 0;
    for (double x : v) a += x;
    return a / static_cast<double>(v.size());
  };
  std::printf(
      "the tail's stages (CrankState, %zu samples >= p99.9 %.1f us; %zu of %zu joined with the "
      "daemon's stamps):\n",
      tail[0].size(), cut, joined, split.size());
  std::printf("  %-46s %9s %9s %9s\n", "stage", "all p50", "tail mean", "tail max");
  std::size_t owner = 0;
  for (std::size_t k = 0; k < kStages; ++k) {
    std::vector<double> sorted = all[k];
    std::sort(sorted.begin(), sorted.end());
    std::printf("  %-46s %9.1f %9.1f %9.1f\n", kNames[k], sorted[sorted.size() / 2], mean(tail[k]),
                *std::max_element(tail[k].begin(), tail[k].end()));
    if (k < 5 && mean(tail[k]) > mean(tail[owner])) owner = k;
  }
  std::printf("the tail's stages: owned by \"%s\" (%.1f us of the tail's mean)\n", kNames[owner],
              mean(tail[owner]));
}

}  // namespace torqued::tools
