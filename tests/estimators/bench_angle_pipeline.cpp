// Google Benchmark: the whole AnglePipeline per tooth with all methods enabled (target ≤ 2 µs median),
// and its parts. Input: a simulated 3000 rpm steady run with CAN signals precomputed per tooth.
// Run: build-*/tests/estimators/bench_angle_pipeline --benchmark_repetitions=5
// --benchmark_report_aggregates_only
// Per-method cost table (BM_Method_*: one estimator's update per tooth on the same input, nothing else).
// Instructions per tooth of each method inside the whole pipeline: run the pipeline benchmark under callgrind
// and divide each update()'s inclusive count by its calls (README, performance section):
//   valgrind --tool=callgrind --callgrind-out-file=cg.out build/tests/estimators/bench_angle_pipeline
//     --benchmark_filter='AllMethods_APS$' --benchmark_min_time=0.2
//   callgrind_annotate --inclusive=yes cg.out | grep -E '::update\(|on_tooth'   (calls: --tree=caller)
// Per-method cost on this input (3000 rpm, all methods, APS): callgrind instructions per tooth (inclusive /
// calls), CPU ns alone from BM_Method_* on the 2-vCPU VM at load 7 (README.md, performance section):
//   method                      instructions (before → now)   CPU ns alone (before → now)
//   ChauvinKalman::update       527 → 457; 593 → 485 (next round); 485 → 408 (round after, no log per tooth);
//                               408 → 388 (lag register shifted in registers, not by a memmove call);
//                               388 → 362 (update_checked: the pipeline's one sample check; 393 → 367 with
//                               the model-miss pole of 4b05a43)
//                                                             82 → 55-59; 68-69 → 61.4-61.6; 62-68 → 54-65
//   FourierObserver::update     500 → 477; 477 → 408 (round after, paired pass); 408 → 389 (unrolled by 2);
//                               389 → 365 (update_checked)
//                                                             35-38 → 35-37; 36-54 → 37-46
//   ToothPreprocessor::update   216 → 211 (round after); 211 → 178 (constants once, update_checked)   21
//   CycleEnergy::update         2 × 158 → 2 × 134 (update_checked, successor by a compare)
//   CycleKeWindow::update       48 → 24 (update_checked)
//   FuelAngleWindow::on_tooth   165 → 153 (fill pass only while an event may be pending)
//   LoadRls::update             146 → 132 (update_checked)      22-24
//   observer_ripple_nm          189 → 102 (next round); 193 → 146 (spark-phased: table pair per
//                               spark change); 146 → 140 (on_tooth's can_fresh)
//   AnglePipeline::on_tooth     2 525 → 2 433; 2 711 → 2 460; 2 489 → 2 338 (round after); 2 432 → 2 385;
//                               2 385 → 2 346 (the Kalman and Fourier changes above); 2 346 → 2 160
//                               (the sample checked once per tooth, and the rows above);
//                               2 351 → 2 165 on 4b05a43
//                                                             225-243 → 217-244; 231-247 → 218-237 (load 9);
//                                                             226-372 → 241-362 (load 5-6: inside the noise);
//                                                             127 → 118-120 (load 3.1-3.4)
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "angle_pipeline.hpp"
#include "chauvin_kalman.hpp"
#include "engine_sim.hpp"
#include "fourier_observer.hpp"
#include "load_rls.hpp"
#include "tooth_error_learner.hpp"
#include "tooth_preprocessor.hpp"

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
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores): Google Benchmark's loop variable
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

static void BM_AnglePipeline_AllMethods_NoKalman(benchmark::State& state) {
  AnglePipelineConfig c = base();
  c.run_kalman = false;
  run(state, c);
}
BENCHMARK(BM_AnglePipeline_AllMethods_NoKalman);

static void BM_AnglePipeline_AllMethods_NoFourier(benchmark::State& state) {
  AnglePipelineConfig c = base();
  c.run_fourier = false;
  run(state, c);
}
BENCHMARK(BM_AnglePipeline_AllMethods_NoFourier);

namespace {
/// One method alone: `update(sample)` per tooth on the same input as the pipeline (reset at its end).
template <class Method, class Update>
void run_method(benchmark::State& state, Method& m, Update update) {
  const Input& in = input();
  std::size_t i = 0;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores): Google Benchmark's loop variable
    update(m, in.samples[i]);
    benchmark::ClobberMemory();
    if (++i == in.samples.size()) {
      i = 0;
      state.PauseTiming();
      m.reset();
      state.ResumeTiming();
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
}  // namespace

static void BM_Method_ToothPreprocessor(benchmark::State& state) {
  ToothPreprocessor m(base().engine, base().wheel, base().preprocess);
  run_method(state, m, [](ToothPreprocessor& x, const ToothSample& s) { x.update(s); });
}
BENCHMARK(BM_Method_ToothPreprocessor);

static void BM_Method_KalmanAPS(benchmark::State& state) {
  ChauvinKalman m(base().engine, base().wheel, base().kalman);
  run_method(state, m, [](ChauvinKalman& x, const ToothSample& s) {
    x.set_model_torque(0.0, true);  // the gas-model gain set, as in the pipeline once MAP is known
    x.update(s);
  });
}
BENCHMARK(BM_Method_KalmanAPS);

static void BM_Method_KalmanExactRiccati(benchmark::State& state) {
  AnglePipelineConfig c = base();
  c.kalman.periodic_gains = false;
  ChauvinKalman m(c.engine, c.wheel, c.kalman);
  run_method(state, m, [](ChauvinKalman& x, const ToothSample& s) {
    x.set_model_torque(0.0, true);
    x.update(s);
  });
}
BENCHMARK(BM_Method_KalmanExactRiccati);

static void BM_Method_Fourier(benchmark::State& state) {
  FourierObserver m(base().engine, base().wheel, base().fourier);
  run_method(state, m, [](FourierObserver& x, const ToothSample& s) {
    x.set_model_torque(0.0, true);
    x.update(s);
  });
}
BENCHMARK(BM_Method_Fourier);

static void BM_Method_LoadRls(benchmark::State& state) {
  LoadRls m(base().engine, base().wheel, base().energies);
  const std::array<double, kMaxCylinders> works{};
  run_method(state, m, [&works](LoadRls& x, const ToothSample& s) {
    x.update(s, 60e3, true, std::nan(""), works, false);
  });
}
BENCHMARK(BM_Method_LoadRls);

// The daemon's chain runs the tooth-error learner beside the pipeline (chain/angle_chain.cpp): per tooth it
// stores the tooth's energy; per cycle it fits the cycle and adds to its sums; every solve_every_cycles the
// table is solved (Arg: solve_every_cycles; 1 = the former per-cycle solve).
static void BM_Method_ToothErrorLearner(benchmark::State& state) {
  ToothLearnParams p;
  p.solve_every_cycles = static_cast<int>(state.range(0));
  ToothErrorLearner m(base().engine, base().wheel, p);
  run_method(state, m, [](ToothErrorLearner& x, const ToothSample& s) { x.update(s); });
}
BENCHMARK(BM_Method_ToothErrorLearner)->Arg(1)->Arg(ToothLearnParams{}.solve_every_cycles);

BENCHMARK_MAIN();
