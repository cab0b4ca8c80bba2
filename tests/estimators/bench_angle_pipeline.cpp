// Google Benchmark: the whole AnglePipeline per tooth with all methods enabled (target ≤ 2 µs median),
// and its parts. Input: a simulated 3000 rpm steady run with CAN signals precomputed per tooth.
// Run: build-*/tests/estimators/bench_angle_pipeline --benchmark_repetitions=5
// --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include <vector>

#include "angle_pipeline.hpp"
#include "engine_sim.hpp"

using namespace torqued;

namespace {
struct Input {
  std::vector<ToothSample> samples;
  std::vector<EngineSignals> sigs;
  sim::Scenario sc;
};
const Input& input() {
  static const Input in = [] {
    Input x;
    x.sc = sim::scenario_by_name("steady_3000_mid");
    x.sc.duration_s = 1.0;
    const auto out = sim::simulate(x.sc);
    x.samples = sim::ideal_tooth_samples(out, x.sc);
    for (const auto& s : x.samples)
      x.sigs.push_back(sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9));
    return x;
  }();
  return in;
}

void run(benchmark::State& state, const AnglePipelineConfig& cfg) {
  const Input& in = input();
  AnglePipeline p(cfg);
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(p.on_tooth(in.samples[i], in.sigs[i]));
    if (++i == in.samples.size()) {
      i = 0;
      state.PauseTiming();
      p.reset();  // time restarts at 0: keep the sequence consistent
      state.ResumeTiming();
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

AnglePipelineConfig base() {
  AnglePipelineConfig c;
  c.engine = input().sc.engine;
  c.wheel = input().sc.wheel;
  return c;
}
}  // namespace

static void BM_AnglePipeline_AllMethods_APS(benchmark::State& state) { run(state, base()); }
BENCHMARK(BM_AnglePipeline_AllMethods_APS);

static void BM_AnglePipeline_AllMethods_ExactRiccati(benchmark::State& state) {
  AnglePipelineConfig c = base();
  c.kalman.periodic_gains = false;
  run(state, c);
}
BENCHMARK(BM_AnglePipeline_AllMethods_ExactRiccati);

static void BM_AnglePipeline_EnergiesChainOnly(benchmark::State& state) {
  AnglePipelineConfig c = base();
  c.run_kalman = false;
  c.run_fourier = false;
  run(state, c);
}
BENCHMARK(BM_AnglePipeline_EnergiesChainOnly);

BENCHMARK_MAIN();
