// bench_recorder (helper "perf2"; not a ctest: timings are reported, not asserted): the per-row cost of the
// CSV recordings (fast replay --record) and of the edge-CSV parser, the two I/O costs of the fast replay.
//   build-perf2/tests/idl/bench_recorder --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <charconv>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "csv_number.hpp"
#include "edge_file_source.hpp"
#include "topic_format.hpp"

namespace {
using namespace torqued;

std::vector<torque_EstimatorTorque> estimator_rows() {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> torque(60.0, 25.0), unc(2.0, 1.0);
  std::vector<torque_EstimatorTorque> v(4096);
  std::int64_t t = 10'160'880;
  for (std::size_t i = 0; i < v.size(); ++i) {
    auto& s = v[i];
    s.engine_id = 1;
    s.method = static_cast<std::uint8_t>(i % 6);
    s.seq = i + 1;
    s.source_t_ns = t += 172'413;
    s.validity = i % 7 == 0 ? 4 : 0;
    s.value_nm = torque(rng);
    s.uncertainty = i % 5 == 0 ? 1e-9 * std::abs(unc(rng)) : std::abs(unc(rng));
    s.health = 0;
  }
  return v;
}

void BM_CsvRowEstimatorTorque(benchmark::State& st) {
  const auto rows = estimator_rows();
  std::string out;
  out.reserve(1 << 20);
  std::size_t i = 0;
  for (auto _ : st) {
    dds::append_csv_row(out, rows[i++ & 4095]);
    if (out.size() > (1u << 19)) out.clear();
  }
  benchmark::DoNotOptimize(out.data());
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_CsvRowEstimatorTorque);

/// The recorder's path: write_csv_row straight into a buffer (no std::string).
void BM_CsvRowEstimatorTorqueRaw(benchmark::State& st) {
  const auto rows = estimator_rows();
  std::vector<char> buf(1 << 20);
  char* p = buf.data();
  char* const end = buf.data() + (1 << 19);
  std::size_t i = 0;
  for (auto _ : st) {
    p = dds::write_csv_row(p, rows[i++ & 4095]);
    if (p > end) p = buf.data();
  }
  benchmark::DoNotOptimize(p);
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_CsvRowEstimatorTorqueRaw);

void BM_CsvRowCrankState(benchmark::State& st) {
  torque_CrankState c{};
  c.engine_id = 1;
  c.tooth = 17;
  c.sync = 2;
  c.phase_known = true;
  std::string out;
  out.reserve(1 << 20);
  std::uint64_t i = 0;
  for (auto _ : st) {
    c.seq = ++i;
    c.source_t_ns = static_cast<std::int64_t>(i) * 3'333'333;
    c.angle_rad = 0.10471975511965977 * static_cast<double>(i % 120);
    c.speed_rad_s = 314.0 + 1e-3 * static_cast<double>(i % 997);
    c.accel_rad_s2 = -20670.286274046175 + static_cast<double>(i % 31);
    dds::append_csv_row(out, c);
    if (out.size() > (1u << 19)) out.clear();
  }
  benchmark::DoNotOptimize(out.data());
  st.SetItemsProcessed(static_cast<std::int64_t>(i));
}
BENCHMARK(BM_CsvRowCrankState);

/// One double: the fixed-point form of the recordings vs the shortest round-trip form it replaced.
template <bool kFixed>
void BM_Double(benchmark::State& st) {
  std::mt19937_64 rng(2);
  std::normal_distribution<double> d(60.0, 25.0);
  std::vector<double> v(4096);
  for (auto& x : v) x = d(rng);
  char buf[64];
  std::size_t i = 0, n = 0;
  for (auto _ : st) {
    const double x = v[i++ & 4095];
    char* e = kFixed ? dds::csv::write_fixed<6>(buf, x) : std::to_chars(buf, buf + 64, x).ptr;
    n += static_cast<std::size_t>(e - buf);
    benchmark::DoNotOptimize(buf);
  }
  st.counters["chars"] = benchmark::Counter(static_cast<double>(n) / static_cast<double>(st.iterations()));
}
BENCHMARK(BM_Double<true>)->Name("BM_DoubleFixed6");
BENCHMARK(BM_Double<false>)->Name("BM_DoubleShortestToChars");

/// Edge CSV parsing (the logic-analyzer export of torque-sim: "<s>.<9 decimals>,crank,cam"), per edge.
/// Arg 1: every row with a leading space (the general parser, as before the fast path).
void BM_EdgeCsvParse(benchmark::State& st) {
  const bool general = st.range(0) != 0;
  const std::string path =
      (std::filesystem::temp_directory_path() / ("bench_recorder_edges_" + std::to_string(general) + ".csv"))
          .string();
  {
    std::FILE* f = std::fopen(path.c_str(), "w");
    std::fputs("Time [s],crank,cam\n", f);
    std::int64_t t = 0;
    for (int i = 0; i <= 100000; ++i, t += 172'413)
      std::fprintf(f, "%s%lld.%09lld,%d,%d\n", general ? " " : "", static_cast<long long>(t / 1'000'000'000),
                   static_cast<long long>(t % 1'000'000'000), i & 1, (i / 120) & 1);
    std::fclose(f);
  }
  std::int64_t edges = 0;
  for (auto _ : st) {
    EdgeCsvSource src(path);
    EdgeEvent e;
    while (src.next(e) == SourceStatus::kOk) ++edges;
  }
  std::filesystem::remove(path);
  st.SetItemsProcessed(edges);
}
BENCHMARK(BM_EdgeCsvParse)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
