// bench_fast_replay (helper "perf2"; not a ctest: timings are reported, not asserted): the whole as-fast-as-
// possible replay (run_fast_replay, all estimators) of a torqued YAML config, with the CSV recorder (Arg 1)
// and without (Arg 0). Reports CPU time per replay and x real time per CPU second (robust on a loaded VM
// where the wall time of `torqued --replay fast` varies 3x), plus instructions are best taken with callgrind
// on torqued.
//   torque-sim -s steady_3000_mid --duration 20 -o /tmp/s3000   (and a config pointing at it, see
//   docs/daemon.md) TORQUED_BENCH_CONFIG=/tmp/s3000.yaml bench_fast_replay --benchmark_repetitions=5
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "backend_factory.hpp"
#include "config_loader.hpp"
#include "fast_replay.hpp"
#include "output_fanout.hpp"
#include "sample_recorder.hpp"
#include "stage_settings_from.hpp"

namespace {
using namespace torqued;

const char* config_path() {
  const char* p = std::getenv("TORQUED_BENCH_CONFIG");
  return p != nullptr ? p : TORQUED_SOURCE_DIR "/config/demo.yaml";
}

void BM_FastReplay(benchmark::State& st) {
  const bool record = st.range(0) != 0;
  const LoadResult lr = load_config(config_path());
  if (!lr.ok()) {
    st.SkipWithError(("config: " + (lr.errors.empty() ? std::string("?") : lr.errors.front())).c_str());
    return;
  }
  const Config& cfg = *lr.config;
  StageSettings s = stage_settings_from(cfg);
  s.decoder = decoder_params(cfg);
  std::string err;
  std::optional<DbcDatabase> dbc = load_dbc(cfg, &err);
  const std::string dir = (std::filesystem::temp_directory_path() / "bench_fast_replay_rec").string();
  double recorded_s = 0.0;
  for (auto _ : st) {
    st.PauseTiming();
    std::filesystem::remove_all(dir);
    std::unique_ptr<EdgeSource> edges = make_edge_source(cfg, &err);
    std::unique_ptr<CanSource> can = make_can_source(cfg, &err);
    auto rec = record ? std::make_unique<dds::SampleRecorder>(dir) : nullptr;
    OutputFanout out(rec.get(), nullptr, s.dds.engine_id);
    st.ResumeTiming();
    const ReplayResult r =
        run_fast_replay(s, edges.get(), can.get(), can_time_offset_ns(cfg), dbc ? &*dbc : nullptr, out);
    if (rec) rec->flush(false);  // the writes belong to the cost of recording (fsync does not)
    st.PauseTiming();
    recorded_s = static_cast<double>(r.last_t_ns - r.first_t_ns) * 1e-9;
    rec.reset();
    st.ResumeTiming();
  }
  std::filesystem::remove_all(dir);
  // x real time = recorded seconds per CPU second of the replay (incl. the stages' start-up)
  st.counters["x_real_time"] =
      benchmark::Counter(recorded_s * static_cast<double>(st.iterations()), benchmark::Counter::kIsRate);
  st.counters["recorded_s"] = recorded_s;
}
BENCHMARK(BM_FastReplay)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
