#include "recording_eval.hpp"

#include <cinttypes>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "angle_chain.hpp"
#include "config_loader.hpp"
#include "csv_table.hpp"
#include "evaluator.hpp"
#include "fast_replay.hpp"
#include "output_fanout.hpp"
#include "replay_inputs.hpp"
#include "sample_recorder.hpp"

namespace torqued::eval {
namespace {

/// Per-cycle rows of the chain's internal values (chain_cycle.csv).
class CycleTap final : public AngleChainSink {
 public:
  explicit CycleTap(std::FILE* f) : f_(f) {
    std::fputs(
        "t_ns,window_start_t_ns,cycle,speed_rad_s,brake_energy_nm,indicated_crank_nm,load_rls_nm,"
        "indicated_eso_nm,friction_nm,brake_crank_nm,fused_nm,fused_quality\n",
        f_);
  }
  void on_tooth(const ChainTooth&) noexcept override {}
  void on_segment(const ChainSegment& s) noexcept override {
    const CycleOutput& o = *s.out;
    if (!o.cycle_end) return;
    std::fprintf(f_, "%" PRId64 ",%" PRId64 ",%" PRIu64 ",%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%d\n",
                 s.source_t_ns, s.window_start_t_ns, s.cycle, o.speed_mean_rad_s, o.brake_energy.torque_nm,
                 o.indicated_crank.torque_nm, o.load_rls.torque_nm, o.indicated_eso.torque_nm,
                 o.friction.torque_nm, o.indicated_crank.torque_nm - o.friction.torque_nm, o.fused.brake_nm,
                 static_cast<int>(o.fused.quality));
  }

 private:
  std::FILE* f_;
};

bool load_csv(const std::string& path, CsvTable& t) {
  std::string err;
  std::vector<std::string> warnings;
  const bool ok = read_csv(path, t, err, warnings);
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
  if (!ok) std::cerr << "error: " << err << "\n";
  return ok;
}

int evaluate_run(const RecordingOptions& opt, std::int64_t first_t_ns) {
  CsvTable engine, chain;
  Truth truth;
  truth.cycle.emplace();
  if (!load_csv(opt.out_dir + "/engine_cycle.csv", engine) ||
      !load_csv(opt.out_dir + "/chain_cycle.csv", chain) || !load_csv(opt.truth_cycle, *truth.cycle))
    return 1;
  EvalOptions eo;
  eo.from_s = static_cast<double>(first_t_ns) * 1e-9 + opt.skip_s;
  std::string err;
  for (auto [table, pairs] :
       {std::pair{&engine,
                  std::vector<std::string>{"fused_nm=t_brake_mean_nm", "brake_nm=t_brake_mean_nm",
                                           "indicated_nm=t_ind_mean_nm", "friction_nm=t_fric_mean_nm"}},
        std::pair{&chain, std::vector<std::string>{"brake_crank_nm=t_brake_mean_nm",
                                                   "indicated_crank_nm=t_ind_mean_nm"}}}) {
    std::vector<PairSpec> specs;
    for (const auto& p : pairs) specs.push_back(*parse_pair(p));
    EvalReport rep;
    if (!evaluate(*table, truth, specs, eo, rep, err)) {
      std::cerr << "error: " << err << "\n";
      return 1;
    }
    std::cout << format_report(rep, eo.tolerance);
  }
  return 0;
}

}  // namespace

int run_recording(const RecordingOptions& opt) {
  const LoadResult lr = load_config(opt.config_path);
  if (!lr.config) {
    for (const auto& e : lr.errors) std::cerr << e << "\n";
    return 2;
  }
  RunInputs in = open_inputs(*lr.config);
  if (!in.ok()) {
    std::cerr << "error: " << in.error << "\n";
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(opt.out_dir, ec);
  dds::SampleRecorder recorder(opt.out_dir);
  std::FILE* f = std::fopen((opt.out_dir + "/chain_cycle.csv").c_str(), "w");
  if (!recorder.ok() || f == nullptr) {
    std::cerr << "error: cannot write to " << opt.out_dir << "\n";
    if (f) std::fclose(f);
    return 1;
  }
  OutputFanout out(&recorder, nullptr, in.settings.dds.engine_id);
  CycleTap tap(f);
  const std::string spath = opt.state_dir.empty() ? "" : opt.state_dir + "/learned_state.txt";
  const StateContext sctx = state_context_from(*lr.config);
  LearnedState st;
  if (!spath.empty()) {  // checked as the daemon checks it (identity, checksum, bounds)
    RestoreResult rs = restore_learned_state(spath, sctx);
    for (const auto& w : rs.warnings) std::cerr << "warning: " << w << "\n";
    if (rs.state) st = *rs.state;
  }
  const ReplayResult r = run_fast_replay(in.settings, in.edges.get(), in.can.get(), in.can_offset_ns,
                                         in.dbc_ptr(), out, nullptr, spath.empty() ? nullptr : &st, &tap);
  recorder.flush(true);
  std::fclose(f);
  if (!r.error.empty()) std::cerr << "warning: replay: " << r.error << "\n";
  std::printf("replayed %.3f s: %" PRIu64 " edges, %" PRIu64 " teeth, %" PRIu64 " cycles, %" PRIu64
              " sync losses; learned state at start: %s\n",
              static_cast<double>(r.last_t_ns - r.first_t_ns) * 1e-9, r.counters.edges, r.counters.teeth,
              r.counters.cycles, r.counters.sync_losses, r.imported.empty() ? "none" : r.imported.c_str());
  if (!spath.empty() && r.learned) {
    std::string serr;
    st.identity = sctx.identity;  // learned by this configuration (as StateSaver does)
    st.version = 2;
    std::filesystem::create_directories(opt.state_dir, ec);
    if (!check_state(st, sctx, spath, &serr) || !save_state_atomic(spath, st, sctx.identity, &serr))
      std::cerr << "warning: learned state not saved: " << serr << "\n";
  }
  if (opt.truth_cycle.empty()) return r.error.empty() ? 0 : 1;
  return evaluate_run(opt, r.first_t_ns);
}

}  // namespace torqued::eval
