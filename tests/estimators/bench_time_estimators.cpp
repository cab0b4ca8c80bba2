// Per-update cost of the time-triggered estimators (targets: UIO ≤ 100 ns, adaptive with time-varying gain
// ≤ 300 ns per update). Inputs vary every call so nothing is constant-folded.
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>

#include "adaptive_tv.hpp"
#include "dirty_diff.hpp"
#include "sliding_mode.hpp"
#include "time_pipeline.hpp"
#include "uio.hpp"

namespace {
using namespace torqued;

std::array<TimeSample, 1024> make_inputs() {
  std::array<TimeSample, 1024> in{};
  for (std::size_t i = 0; i < in.size(); ++i) {
    const double t = 0.001 * static_cast<double>(i);
    in[i].t_ns = static_cast<std::int64_t>(i) * 1'000'000;
    in[i].dt_s = 0.001;
    in[i].speed_rad_s = 230.0 + 10.0 * std::sin(7.0 * t);
    in[i].load_torque_nm = 50.0 + 5.0 * std::sin(3.0 * t);
    in[i].maf_kg_s = 0.015 + 0.003 * std::sin(11.0 * t);
    in[i].speed = in[i].load = in[i].maf = InputStatus::kOk;
  }
  return in;
}

template <typename Est>
void run(benchmark::State& state, Est& est) {
  static const auto in = make_inputs();
  std::size_t i = 0;
  for (auto _ : state) {
    est.update(in[i++ & 1023]);
    benchmark::DoNotOptimize(est.estimate().torque_nm);
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_Uio(benchmark::State& s) {
  Uio e(UioParams{}, 0.14);
  run(s, e);
}
void BM_SlidingMode(benchmark::State& s) {
  SlidingMode e(SlidingModeParams{}, 0.14);
  run(s, e);
}
void BM_DirtyDiff(benchmark::State& s) {
  DirtyDiff e(DirtyDiffParams{}, 0.14);
  run(s, e);
}
void BM_AdaptiveConstantGain(benchmark::State& s) {
  AdaptiveParams p;
  p.time_varying_gain = false;
  AdaptiveTv e(p, 0.14);
  run(s, e);
}
void BM_AdaptiveTimeVaryingGain(benchmark::State& s) {
  AdaptiveTv e(AdaptiveParams{}, 0.14);
  run(s, e);
}
void BM_TimePipelineAllFour(benchmark::State& s) {
  TimePipelineParams p;
  p.inertia_kgm2 = 0.14;
  TimePipeline e(p, TimeEstimatorParams{}, EngineGeometry{});
  static const auto in = make_inputs();
  std::size_t i = 0;
  for (auto _ : s) {
    benchmark::DoNotOptimize(e.step(in[i++ & 1023]).uio.torque_nm);
  }
  s.SetItemsProcessed(s.iterations());
}
void BM_MeanSpeedTracker(benchmark::State& s) {
  MeanSpeedTracker tr;
  ToothSample t;
  t.synced = true;
  t.width_rad = 6.0 * 3.141592653589793 / 180.0;
  double dt = 0.0004;
  for (auto _ : s) {
    t.dt_s = dt;
    dt = dt == 0.0004 ? 0.00041 : 0.0004;
    tr.update(t);
    benchmark::DoNotOptimize(tr.speed_rad_s());
  }
  s.SetItemsProcessed(s.iterations());
}

BENCHMARK(BM_Uio);
BENCHMARK(BM_SlidingMode);
BENCHMARK(BM_DirtyDiff);
BENCHMARK(BM_AdaptiveConstantGain);
BENCHMARK(BM_AdaptiveTimeVaryingGain);
BENCHMARK(BM_TimePipelineAllFour);
BENCHMARK(BM_MeanSpeedTracker);
}  // namespace

BENCHMARK_MAIN();
