// Per-tooth cost of the angle-domain estimators (helper "angle"): pre-processing, Chauvin Kalman with
// asymptotic periodic gains (APS) vs exact Riccati (paper Table I: 11x), Fourier observer, tooth-error
// learner. Not a ctest: figures are reported in docs/angle_estimators.md. Run:
// build/tests/estimators/bench_angle_estimators
#include <benchmark/benchmark.h>

#include "chauvin_kalman.hpp"
#include "fourier_observer.hpp"
#include "synthetic_crank.hpp"
#include "tooth_error_learner.hpp"
#include "tooth_preprocessor.hpp"

namespace {

using namespace torqued;

const test::SyntheticRun& run() {
  static const test::SyntheticRun r = [] {
    test::SyntheticSpec sp;
    sp.rpm = 3000.0;
    sp.cycles = 20;
    return test::make_synthetic(sp);
  }();
  return r;
}

template <typename Estimator>
void feed(benchmark::State& state, Estimator& e) {
  const auto& s = run().samples;
  std::size_t i = 1;
  for (auto _ : state) {
    e.update(s[i]);
    benchmark::ClobberMemory();
    if (++i == s.size()) i = 1;
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_ToothPreprocessor(benchmark::State& state) {
  ToothPreprocessor p(EngineGeometry{}, WheelGeometry{}, PreprocessParams{});
  feed(state, p);
}
void BM_KalmanAps(benchmark::State& state) {
  KalmanParams kp;
  ChauvinKalman k(EngineGeometry{}, WheelGeometry{}, kp);
  feed(state, k);
}
void BM_KalmanExactRiccati(benchmark::State& state) {
  KalmanParams kp;
  kp.periodic_gains = false;
  ChauvinKalman k(EngineGeometry{}, WheelGeometry{}, kp);
  feed(state, k);
}
void BM_KalmanApsPaperOrder(benchmark::State& state) {  // lag 0 (the paper's predictor); same state size
  KalmanParams kp;
  kp.smoother_lag = 0;
  ChauvinKalman k(EngineGeometry{}, WheelGeometry{}, kp);
  feed(state, k);
}
void BM_FourierObserver(benchmark::State& state) {
  FourierParams fp;
  fp.harmonics = static_cast<int>(state.range(0));
  FourierObserver f(EngineGeometry{}, WheelGeometry{}, fp);
  feed(state, f);
}
void BM_ToothErrorLearner(benchmark::State& state) {
  ToothErrorLearner l(EngineGeometry{}, WheelGeometry{}, ToothLearnParams{});
  feed(state, l);
}

BENCHMARK(BM_ToothPreprocessor);
BENCHMARK(BM_KalmanAps);
BENCHMARK(BM_KalmanExactRiccati);
BENCHMARK(BM_KalmanApsPaperOrder);
BENCHMARK(BM_FourierObserver)->Arg(5)->Arg(12)->Arg(20);
BENCHMARK(BM_ToothErrorLearner);

}  // namespace

BENCHMARK_MAIN();
