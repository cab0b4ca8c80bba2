#include "daemon_bed.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <tuple>
#include <vector>

#include "config_loader.hpp"
#include "fast_replay.hpp"
#include "replay_inputs.hpp"
#include "sim_writer.hpp"
#include "state_store.hpp"

namespace torqued::eval {
namespace {
namespace fs = std::filesystem;
constexpr double kFourPi = 4.0 * std::numbers::pi;

struct NoSink final : SampleSink {
  void emit(const dds::AnySample&) noexcept override {}
};

/// One cycle-end record of the chain.
struct Row {
  double t0_s = 0.0, t1_s = 0.0;
  TorqueEstimate brake, indicated, friction, indicated_crank;
  double fused = 0.0, fused_sd = 0.0;
  bool fused_valid = false;
  bool fused_prior_only = false;  ///< the fused value rests on the priors alone (quality prior_only)
  ReferenceKind reference = ReferenceKind::kNone;
};

struct Tap final : AngleChainSink {
  std::vector<Row> rows;
  void on_tooth(const ChainTooth&) noexcept override {}
  void on_segment(const ChainSegment& s) noexcept override {
    const CycleOutput& o = *s.out;
    if (!o.cycle_end || s.window_start_t_ns >= s.source_t_ns) return;
    Row r;
    r.t0_s = static_cast<double>(s.window_start_t_ns) * 1e-9;
    r.t1_s = static_cast<double>(s.source_t_ns) * 1e-9;
    r.brake = o.brake;
    r.indicated = o.indicated;
    r.friction = o.friction;
    r.indicated_crank = o.indicated_crank;
    r.reference = o.reference;
    r.fused = o.fused.brake_nm;
    r.fused_sd = o.fused.sd_nm;
    r.fused_valid = o.fused.quality != FusionQuality::kInvalid;
    r.fused_prior_only = o.fused.quality == FusionQuality::kPriorOnly;
    rows.push_back(r);
  }
};

/// Truth of the chain's cycle-end window (t0, t1]: the simulator's cycle whose end is nearest t1 (the chain's
/// boundary-0 windows close on the same crank angle as the simulator's cycles), accepted within an eighth of
/// a cycle. Per-tooth truth averaged over the window would be biased by the tooth sampling (gap, firing
/// peaks).
struct WindowTruth {
  double brake = 0.0, ind = 0.0, fric = 0.0, rpm = 0.0;
  bool ok = false;
  bool fuel_cut =
      false;  ///< this cycle or the one before had a cylinder's fuel cut (a window may straddle it)
};
WindowTruth window_truth(const sim::SimOutput& out, double t0, double t1) {
  WindowTruth w;
  const auto& cy = out.cycles;
  auto it = std::lower_bound(cy.begin(), cy.end(), t1,
                             [](const sim::CycleTruth& c, double v) { return c.t_end_s < v; });
  const sim::CycleTruth* best = nullptr;
  for (auto c = it == cy.begin() ? it : it - 1; c != cy.end() && c <= it; ++c) {
    if (!best || std::fabs(c->t_end_s - t1) < std::fabs(best->t_end_s - t1)) best = &*c;
  }
  if (!best || std::fabs(best->t_end_s - t1) > 0.125 * (t1 - t0)) return w;
  w.brake = best->t_brake_mean_nm;
  w.ind = best->t_ind_mean_nm;
  w.fric = best->t_fric_mean_nm;
  w.rpm = best->speed_mean_rad_s * 30.0 / std::numbers::pi;
  w.fuel_cut = best->fuel_cut || (best != &cy.front() && (best - 1)->fuel_cut);
  w.ok = true;
  return w;
}

void add(DaemonBedStats& s, double est, double truth, double sd, bool transient, double tight_rel = 0.03) {
  const double err = est - truth;
  if (std::fabs(err) <= std::max(tight_rel * std::fabs(truth), 2.0)) ++s.tight;
  if (std::fabs(err) <= std::max(0.08 * std::fabs(truth), 5.0)) ++s.loose;
  const double allowed =
      transient ? std::max(0.08 * std::fabs(truth), 5.0) : std::max(0.05 * std::fabs(truth), 3.0);
  ++s.n;
  if (std::fabs(err) <= allowed) ++s.pass;
  if (std::fabs(err) <= sd) ++s.covered;
  if (std::fabs(err) <= 2.0 * sd) ++s.covered2;
  s.rms_nm += err * err;
  s.rms_true_nm += truth * truth;
  s.bias_nm += err;
  s.max_abs_nm = std::max(s.max_abs_nm, std::fabs(err));
}
void finish(DaemonBedStats& s) {
  if (s.n == 0) return;
  s.rms_nm = std::sqrt(s.rms_nm / s.n);
  s.rms_true_nm = std::sqrt(s.rms_true_nm / s.n);
  s.bias_nm /= s.n;
}

DaemonBedRun score(const std::vector<Row>& rows, const sim::SimOutput& out, int skip, const fs::path& csv,
                   double t_min_s = -1e300, double t_max_s = 1e300) {
  DaemonBedRun r;
  std::string text =
      "t_s,transient,brake_true_nm,brake_nm,brake_sd_nm,indicated_true_nm,indicated_nm,indicated_sd_nm,"
      "friction_true_nm,friction_nm,fused_nm,fused_sd_nm,indicated_crank_nm,indicated_crank_sd_nm\n";
  double prev_true = 0.0, prev_rpm = 0.0;
  bool have_prev = false;
  int hold = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& x = rows[i];
    const WindowTruth w = window_truth(out, x.t0_s, x.t1_s);
    if (!w.ok) continue;
    // Transient as in pipeline_eval: the true brake torque or the speed moves between consecutive cycles.
    if (have_prev && (std::fabs(w.brake - prev_true) > 1.5 || std::fabs(w.rpm - prev_rpm) > 0.01 * prev_rpm))
      hold = 2;
    const bool transient = hold > 0;
    if (hold > 0) --hold;
    prev_true = w.brake;
    prev_rpm = w.rpm;
    have_prev = true;
    if (static_cast<int>(i) < skip || x.t0_s < t_min_s || x.t1_s > t_max_s) continue;
    ++r.cycles;
    if (x.fused_valid) ++r.fused_published;
    add(r.brake, x.brake.torque_nm, w.brake, x.brake.uncertainty, transient);
    add(r.indicated, x.indicated.torque_nm, w.ind, x.indicated.uncertainty, transient);
    add(r.friction, x.friction.torque_nm, w.fric, x.friction.uncertainty, transient, 0.10);
    if (x.fused_valid) {
      add(r.fused, x.fused, w.brake, x.fused_sd, transient);
      add(r.fused_friction_exact, x.fused + (x.friction.torque_nm - w.fric), w.brake, x.fused_sd, transient);
      add(r.fused_indicated_exact, x.fused - (x.indicated.torque_nm - w.ind), w.brake, x.fused_sd, transient);
    }
    char line[320];
    std::snprintf(line, sizeof line, "%.6f,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n",
                  x.t1_s, transient ? 1 : 0, w.brake, x.brake.torque_nm, x.brake.uncertainty, w.ind,
                  x.indicated.torque_nm, x.indicated.uncertainty, w.fric, x.friction.torque_nm, x.fused,
                  x.fused_sd, x.indicated_crank.torque_nm, x.indicated_crank.uncertainty);
    text += line;
  }
  sim::write_text_file(csv, text);
  for (DaemonBedStats* s :
       {&r.brake, &r.indicated, &r.friction, &r.fused, &r.fused_friction_exact, &r.fused_indicated_exact})
    finish(*s);
  return r;
}

/// Replays `config` from `state_in` (may be null); the learned state at the end into `state_out` (may be
/// null).
bool replay(const fs::path& config, const LearnedState* state_in, LearnedState* state_out, Tap& tap,
            std::string* imported, std::string& error) {
  const LoadResult lr = load_config(config.string());
  if (!lr.config) {
    error = config.string() + ": " + (lr.errors.empty() ? std::string("invalid") : lr.errors.front());
    return false;
  }
  RunInputs in = open_inputs(*lr.config);
  if (!in.ok()) {
    error = config.string() + ": " + in.error;
    return false;
  }
  NoSink sink;
  LearnedState st;
  if (state_in) st = *state_in;
  const ReplayResult rr = run_fast_replay(in.settings, in.edges.get(), in.can.get(), in.can_offset_ns,
                                          in.dbc_ptr(), sink, nullptr, &st, &tap);
  if (!rr.error.empty()) {
    error = config.string() + ": replay: " + rr.error;
    return false;
  }
  if (imported) *imported = rr.imported;
  if (state_out && rr.learned) {
    // Saved and restored exactly as the daemon does (identity, checksum, physical bounds).
    const StateContext ctx = state_context_from(*lr.config);
    const std::string path = (config.parent_path() / "state" / "learned_state.txt").string();
    st.identity = ctx.identity;
    st.version = 2;
    if (!check_state(st, ctx, path, &error) || !save_state_atomic(path, st, ctx.identity, &error))
      return false;
    const RestoreResult rs = restore_learned_state(path, ctx);
    if (!rs.state) {
      error = path + ": " + (rs.warnings.empty() ? std::string("not restored") : rs.warnings.front());
      return false;
    }
    *state_out = *rs.state;
  }
  return true;
}
}  // namespace

bool evaluate_bed_engine_daemon(const sim::BedEngine& e, const DaemonBedOptions& opt, DaemonBedResult& r,
                                std::string& error) {
  r = DaemonBedResult{};
  r.engine = e.name;
  try {
    const fs::path dir = fs::path(opt.out_dir) / e.name;
    const sim::Scenario learn = sim::bed_learning_run(e);
    const sim::SimOutput learn_out = sim::simulate(learn);
    sim::write_recording(learn_out, learn, e.spec, dir / "learn");
    LearnedState st;
    Tap learn_tap;
    if (!replay(dir / "learn" / "torqued.yaml", nullptr, &st, learn_tap, nullptr, error)) return false;
    if (st.inertia) r.inertia_scale = (*st.inertia)[0];
    r.inertia_true_scale = e.truth.engine.j_rot_kgm2 / e.spec.j_rot_kgm2;
    const sim::Scenario ev = sim::bed_eval_run(e, opt.short_run);
    const sim::SimOutput ev_out = sim::simulate(ev);
    sim::write_recording(ev_out, ev, e.spec, dir / "eval");
    Tap with, without;
    if (!replay(dir / "eval" / "torqued.yaml", &st, nullptr, with, &r.learned, error) ||
        !replay(dir / "eval" / "torqued_noload.yaml", &st, nullptr, without, nullptr, error))
      return false;
    r.with_load = score(with.rows, ev_out, opt.skip_cycles, dir / "eval" / "cycles_load.csv");
    r.without_load = score(without.rows, ev_out, opt.skip_cycles, dir / "eval" / "cycles_noload.csv");
  } catch (const std::exception& ex) {
    error = e.name + ": " + ex.what();
    return false;
  }
  return true;
}

namespace {
/// Writes `yaml` next to the recording and replays it from a fresh state.
bool replay_text(const fs::path& dir, const std::string& name, const std::string& yaml, Tap& tap,
                 std::string& error) {
  sim::write_text_file(dir / name, yaml);
  return replay(dir / name, nullptr, nullptr, tap, nullptr, error);
}
std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const auto p = s.find(from);
  if (p != std::string::npos) s.replace(p, from.size(), to);
  return s;
}
/// Cycles the chain took as a free coast-down (no flag), and of them those where the simulator's clutch was
/// closed at either end of the window (a wrong one: the vehicle's load taken for the accessories').
void count_free_coast(const std::vector<Row>& rows, const sim::Scenario& sc, VehicleBedResult& r) {
  for (const Row& x : rows) {
    if (x.reference != ReferenceKind::kFreeCoast) continue;
    ++r.free_coast_cycles;
    if (sim::evaluate(sc.vehicle.clutch_closed, x.t0_s, 1.0) > 0.5 ||
        sim::evaluate(sc.vehicle.clutch_closed, x.t1_s, 1.0) > 0.5)
      ++r.free_coast_wrong;
  }
}
/// A second drive of the same vehicle: the same recording from the state the first left (saved and restored
/// as the daemon does), with no flag (what the free coast-down and its idle taught) and with the neutral
/// flag.
bool second_drives(const fs::path& vd, const sim::SimOutput& ve_out, const DaemonBedOptions& opt,
                   VehicleBedResult& r, std::string& error) {
  for (const auto& [yaml, label, csv] :
       {std::tuple{"torqued_noflag.yaml", "vehicle/noflag 2nd", "cycles_noflag_2nd.csv"},
        std::tuple{"torqued_neutral.yaml", "vehicle/neutral 2nd", "cycles_neutral_2nd.csv"}}) {
    LearnedState st;
    Tap first, second;
    if (!replay(vd / yaml, nullptr, &st, first, nullptr, error) ||
        !replay(vd / yaml, &st, nullptr, second, nullptr, error))
      return false;
    r.runs.push_back({label, score(second.rows, ve_out, opt.skip_cycles, vd / csv)});
    if (std::string(yaml) == "torqued_noflag.yaml") r.noflag_saved_friction = st.friction.has_value();
  }
  return true;
}

/// (c): a learning run with the load signal at one operating point (plus an overrun and idle), its state
/// saved and restored as the daemon does; then the map recording without its load signal from that state
/// (one-point/map) and from a fresh state (never/map).
bool one_point_runs(const sim::BedEngine& e, const DaemonBedOptions& opt, const fs::path& dir,
                    VehicleBedResult& r, std::string& error) {
  const sim::Scenario learn = sim::bed_one_point_learning_run(e);
  const sim::SimOutput learn_out = sim::simulate(learn);
  sim::write_recording(learn_out, learn, e.spec, dir / "one_point");
  LearnedState st;
  Tap learn_tap;
  if (!replay(dir / "one_point" / "torqued.yaml", nullptr, &st, learn_tap, nullptr, error)) return false;
  (void)score(learn_tap.rows, learn_out, 0, dir / "one_point" / "cycles_learn.csv");  // for inspection
  const sim::Scenario ev = sim::bed_eval_run(e, opt.short_run);
  const sim::SimOutput ev_out = sim::simulate(ev);
  const fs::path md = dir / "map";
  sim::write_recording(ev_out, ev, e.spec, md);
  Tap taught, never;
  if (!replay(md / "torqued_noload.yaml", &st, nullptr, taught, nullptr, error) ||
      !replay(md / "torqued_noload.yaml", nullptr, nullptr, never, nullptr, error))
    return false;
  r.runs.push_back(
      {"one-point/map", score(taught.rows, ev_out, opt.skip_cycles, md / "cycles_one_point.csv")});
  r.runs.push_back({"never/map", score(never.rows, ev_out, opt.skip_cycles, md / "cycles_never.csv")});
  return true;
}
}  // namespace

bool evaluate_prior_calibration_engine(const sim::BedEngine& e, const DaemonBedOptions& opt,
                                       PriorCalibration& r, std::string& error) {
  r = PriorCalibration{};
  r.engine = e.name;
  try {
    const sim::Scenario ev = sim::bed_eval_run(e, opt.short_run);
    const sim::SimOutput out = sim::simulate(ev);
    const fs::path md = fs::path(opt.out_dir) / e.name / "map";
    sim::write_recording(out, ev, e.spec, md);
    Tap never;
    if (!replay(md / "torqued_noload.yaml", nullptr, nullptr, never, nullptr, error)) return false;
    for (std::size_t i = static_cast<std::size_t>(opt.skip_cycles); i < never.rows.size(); ++i) {
      const Row& x = never.rows[i];
      const WindowTruth w = window_truth(out, x.t0_s, x.t1_s);
      if (!w.ok || w.fuel_cut || !x.fused_prior_only || !(x.friction.uncertainty > 0.0) ||
          !(x.fused_sd > 0.0))
        continue;
      // In (or next to) a fuel cut-off the fuel model is its pumping term alone, which none of the priors'
      // efficiency terms explain: left out. Elsewhere the prior slot is fuel model − friction with both 1σ
      // (fuel_prior_brake): the fuel model's own part is recovered from the fused 1σ.
      const double fuel_ind = x.fused + x.friction.torque_nm;
      const double fuel_sd =
          std::sqrt(std::max(0.0, x.fused_sd * x.fused_sd - x.friction.uncertainty * x.friction.uncertainty));
      r.friction_rel.push_back((x.friction.torque_nm - w.fric) / x.friction.torque_nm);
      r.friction_z.push_back(std::fabs(x.friction.torque_nm - w.fric) / x.friction.uncertainty);
      r.fuel_rel.push_back((fuel_ind - w.ind) / fuel_ind);
      if (fuel_sd > 0.0) r.fuel_z.push_back(std::fabs(fuel_ind - w.ind) / fuel_sd);
      r.fused_z.push_back(std::fabs(x.fused - w.brake) / x.fused_sd);
    }
  } catch (const std::exception& ex) {
    error = e.name + ": " + ex.what();
    return false;
  }
  return true;
}

bool evaluate_vehicle_bed_engine(const sim::BedEngine& e, const DaemonBedOptions& opt, VehicleBedResult& r,
                                 std::string& error) {
  r = VehicleBedResult{};
  r.engine = e.name;
  try {
    const fs::path dir = fs::path(opt.out_dir) / e.name;
    double td = 0.0;
    sim::Scenario hy = sim::bed_hybrid_run(e, opt.short_run, &td);
    hy.vehicle.flag_lag_s = opt.vehicle_flag_lag_s;
    const sim::SimOutput hy_out = sim::simulate(hy);
    const fs::path hd = dir / "hybrid";
    sim::write_recording(hy_out, hy, e.spec, hd);
    const std::string flag = sim::torqued_config_yaml(e.spec, hy, false, true);
    const std::string noflag = sim::torqued_config_yaml(e.spec, hy, false, false);
    Tap a, b, c;
    if (!replay_text(hd, "torqued_flag.yaml", flag, a, error) ||
        !replay_text(hd, "torqued_static_false.yaml", noflag, b, error) ||
        !replay_text(hd, "torqued_static_true.yaml", replaced(noflag, "sole_load: false", "sole_load: true"),
                     c, error))
      return false;
    const double settle = 0.5;  // s after the clutch closed: the flag's lead, the 720° windows across it
    r.runs.push_back(
        {"hybrid/open", score(a.rows, hy_out, opt.skip_cycles, hd / "cycles_open.csv", 0.0, td)});
    r.runs.push_back({"hybrid/drive", score(a.rows, hy_out, 0, hd / "cycles_drive.csv", td + settle)});
    r.runs.push_back(
        {"hybrid/drive static-false", score(b.rows, hy_out, 0, hd / "cycles_sf.csv", td + settle)});
    r.runs.push_back(
        {"hybrid/drive static-true", score(c.rows, hy_out, 0, hd / "cycles_st.csv", td + settle)});
    sim::Scenario ve = sim::bed_vehicle_run(e, opt.short_run);
    ve.vehicle.flag_lag_s = opt.vehicle_flag_lag_s;
    const sim::SimOutput ve_out = sim::simulate(ve);
    const fs::path vd = dir / "vehicle";
    sim::write_recording(ve_out, ve, e.spec, vd);
    Tap n, f;
    if (!replay_text(vd, "torqued_noflag.yaml", sim::torqued_config_yaml(e.spec, ve, false, false), n,
                     error) ||
        !replay_text(vd, "torqued_neutral.yaml", sim::torqued_config_yaml(e.spec, ve, false, true), f, error))
      return false;
    r.runs.push_back({"vehicle/noflag", score(n.rows, ve_out, opt.skip_cycles, vd / "cycles_noflag.csv")});
    r.runs.push_back({"vehicle/neutral", score(f.rows, ve_out, opt.skip_cycles, vd / "cycles_neutral.csv")});
    count_free_coast(n.rows, ve, r);
    if (!second_drives(vd, ve_out, opt, r, error)) return false;
    if (!one_point_runs(e, opt, dir, r, error)) return false;
  } catch (const std::exception& ex) {
    error = e.name + ": " + ex.what();
    return false;
  }
  return true;
}

}  // namespace torqued::eval
