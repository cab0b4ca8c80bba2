// Google Benchmark for io/ (not a ctest; figures go into docs/io.md):
//   edges decoded per second (crank decoder), edge CSV parsing MB/s, candump parsing lines/s and MB/s,
//   signal-store frames/s. Run: build-io/tests/io/bench_io
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdio>
#include <string>

#include "candump_source.hpp"
#include "crank_decoder.hpp"
#include "dbc.hpp"
#include "edge_file_source.hpp"
#include "signal_store.hpp"
#include "synthetic_wheel.hpp"

namespace torqued {
namespace {

const test::SynthOutput& synth() {
  static const test::SynthOutput s = [] {
    test::SynthOptions o;
    o.rpm0 = 1000;
    o.rpm1 = 6000;
    o.ripple = 0.05;
    o.duration_s = 2.0;
    o.step_s = 5e-6;
    return test::synthesize(o);
  }();
  return s;
}

void BM_DecodeEdges(benchmark::State& state) {
  const auto& s = synth();
  CrankDecoder dec(WheelGeometry{}, DecoderParams{});
  ToothEvent ev;
  std::uint64_t teeth = 0;
  for (auto _ : state) {
    dec.reset();  // each pass is the same 2 s recording (1000 -> 6000 rpm), from no signal to synced
    for (const EdgeEvent& e : s.edges) teeth += dec.on_edge(e, ev) ? 1 : 0;
    benchmark::DoNotOptimize(ev);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * s.edges.size()));
  state.counters["edges/s"] = benchmark::Counter(static_cast<double>(state.iterations() * s.edges.size()),
                                                 benchmark::Counter::kIsRate);
  state.counters["sync_losses"] = static_cast<double>(dec.stats().sync_losses);
}
BENCHMARK(BM_DecodeEdges)->Unit(benchmark::kMillisecond);

std::string temp_path(const char* name) {
  return "/tmp/torqued_bench_" + std::to_string(::getpid()) + "_" + name;
}

const std::string& edge_csv_file() {
  static const std::string path = [] {
    const std::string p = temp_path("edges.csv");
    std::FILE* f = std::fopen(p.c_str(), "w");
    std::fputs("Time [s],crank,cam\n0.000000000,0,0\n", f);
    int lv[2] = {0, 0};
    std::int64_t base = 0;
    for (int rep = 0; rep < 20; ++rep) {  // ~40 s of 1000-6000 rpm, ~30 MB
      for (const auto& e : synth().edges) {
        lv[e.channel] = e.level;
        const std::int64_t t = base + e.t_ns;
        std::fprintf(f, "%lld.%09lld,%d,%d\n", static_cast<long long>(t / 1'000'000'000),
                     static_cast<long long>(t % 1'000'000'000), lv[0], lv[1]);
      }
      base += synth().edges.back().t_ns + 1000;
    }
    std::fclose(f);
    return p;
  }();
  return path;
}

void BM_EdgeCsvParse(benchmark::State& state) {
  const std::string& path = edge_csv_file();
  std::uint64_t bytes = 0, records = 0;
  for (auto _ : state) {
    EdgeCsvSource src(path);
    EdgeEvent e;
    while (src.next(e) == SourceStatus::kOk) benchmark::DoNotOptimize(e);
    bytes += src.stats().bytes;
    records += src.stats().records;
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.counters["edges/s"] = benchmark::Counter(static_cast<double>(records), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EdgeCsvParse)->Unit(benchmark::kMillisecond);

const std::string& candump_file() {
  static const std::string path = [] {
    const std::string p = temp_path("can.log");
    std::FILE* f = std::fopen(p.c_str(), "w");
    for (int i = 0; i < 600'000;
         ++i) {  // ~27 MB: 100 Hz x 4 messages x 25 min, plus some FD and extended frames
      const long long us = 1'700'000'000'000'000LL + i * 2500LL;
      if (i % 50 == 7) {
        std::fprintf(f, "(%lld.%06lld) can1 18FF0102##100112233445566778899AABBCCDDEEFF\n", us / 1'000'000,
                     us % 1'000'000);
      } else {
        std::fprintf(f, "(%lld.%06lld) can0 %03X#%02X11223344556677\n", us / 1'000'000, us % 1'000'000,
                     0x100 + i % 4, i & 0xFF);
      }
    }
    std::fclose(f);
    return p;
  }();
  return path;
}

void BM_CandumpParse(benchmark::State& state) {
  const std::string& path = candump_file();
  std::uint64_t bytes = 0, lines = 0;
  for (auto _ : state) {
    CandumpSource src(path);
    CanFrame c;
    while (src.next(c) == SourceStatus::kOk) benchmark::DoNotOptimize(c);
    bytes += src.stats().bytes;
    lines += src.stats().lines;
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.counters["lines/s"] = benchmark::Counter(static_cast<double>(lines), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CandumpParse)->Unit(benchmark::kMillisecond);

void BM_SignalStoreFrame(benchmark::State& state) {
  const auto r = DbcDatabase::parse_string(
      "BO_ 256 ENGINE_1: 8 ECU\n SG_ EngineSpeed : 0|16@1+ (0.25,0) [0|16383.75] \"rpm\" X\n"
      " SG_ MAP : 16|16@1+ (0.01,0) [0|655.35] \"kPa\" X\n SG_ IntakeAirTemp : 32|8@1- (1,0) [-40|125] "
      "\"degC\" X\n"
      " SG_ Throttle : 47|8@0+ (0.4,0) [0|102] \"%\" X\n",
      "bench");
  SignalStore store(*r.db);
  store.bind(Quantity::kMap, "ENGINE_1", "MAP", 100'000'000, nullptr);
  store.bind(Quantity::kIntakeTemp, "ENGINE_1", "IntakeAirTemp", 100'000'000, nullptr);
  store.bind(Quantity::kThrottle, "ENGINE_1", "Throttle", 100'000'000, nullptr);
  CanFrame f;
  f.id = 0x100;
  f.len = 8;
  f.data = {0xE0, 0x2E, 0x92, 0x27, 0xFB, 100, 0, 0};
  for (auto _ : state) {
    f.t_ns += 10'000;
    store.on_frame(f);
    benchmark::DoNotOptimize(store.signals_at(f.t_ns));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SignalStoreFrame);

}  // namespace
}  // namespace torqued

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::remove(torqued::edge_csv_file().c_str());
  std::remove(torqued::candump_file().c_str());
  return 0;
}
