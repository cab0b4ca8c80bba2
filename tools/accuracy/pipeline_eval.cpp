#include "pipeline_eval.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>
#include <set>
#include <tuple>
#include <utility>

#include "crank_kinematics.hpp"
#include "tooth_error_learner.hpp"

namespace torqued::eval {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr double kDeg = std::numbers::pi / 180.0;

double wrap4pi(double a) {
  a = std::fmod(a, kFourPi);
  return a < 0.0 ? a + kFourPi : a;
}

void add(ErrorStats& s, double est, double truth, double pct, double nm, double sd = -1.0) {
  const double err = est - truth;
  if (sd > 0.0) {
    ++s.with_sd;
    if (std::fabs(err) <= sd) ++s.covered;
  }
  const double allowed = std::max(pct * 0.01 * std::fabs(truth), nm);
  ++s.n;
  if (std::fabs(err) <= allowed) ++s.pass;
  s.max_abs_nm = std::max(s.max_abs_nm, std::fabs(err));
  s.rms_nm += err * err;
  if (std::fabs(truth) > 1e-6)
    s.max_rel_pct = std::max(s.max_rel_pct, 100.0 * std::fabs(err) / std::fabs(truth));
  s.worst_ratio = std::max(s.worst_ratio, std::fabs(err) / allowed);
}
void finish(ErrorStats& s) { s.rms_nm = s.n > 0 ? std::sqrt(s.rms_nm / s.n) : 0.0; }

struct LearnedTable {
  std::vector<double> ratio;
  std::uint64_t cycles = 0;
  bool low_orders = false;
};
}  // namespace

sim::Scenario warmup_scenario(const sim::Scenario& sc) {
  sim::Scenario w;
  w.name = sc.name + "_warmup";
  w.seed = sc.seed;  // same wheel (the machining errors are drawn from the seed)
  w.engine = sc.engine;
  w.wheel = sc.wheel;
  w.sensors = sc.sensors;
  w.combustion = sc.combustion;
  w.air = sc.air;
  w.dyno = sc.dyno;
  w.fuel_factor = sc.fuel_factor;  // the engine's injectors as they are
  w.friction = sc.friction;
  w.spark_offset_deg = sc.spark_offset_deg;
  w.intake_temp_c = sc.intake_temp_c;
  w.step_deg = sc.step_deg;
  w.duration_s = 5.0;
  // 1 s plateaus (≈ 8/16/25/33 cycles), 0.3 s ramps (rejected by the learner's steadiness test), dyno-held
  // fuel cut-off at 4000 rpm for the last 0.7 s (motored cycles).
  w.speed_rpm = {{0.0, 1000.0}, {1.0, 1000.0}, {1.3, 2000.0}, {2.0, 2000.0},
                 {2.3, 3000.0}, {3.0, 3000.0}, {3.3, 4000.0}, {5.0, 4000.0}};
  w.map_target_kpa = {{0.0, 65.0}};
  w.fuel_cuts = {{4.3, 5.0, 1000.0}};
  return w;
}

std::vector<double> learned_width_ratios(const sim::Scenario& sc, const ToothLearnParams& params,
                                         std::uint64_t* cycles, bool* low_orders) {
  static std::mutex mu;
  static std::map<std::tuple<std::uint64_t, int, int, int, int, double>, LearnedTable> cache;
  const auto key = std::make_tuple(sc.seed, sc.engine.cylinders, sc.wheel.positions, sc.wheel.missing,
                                   params.min_cycles, params.speed_weight_exp);
  std::lock_guard<std::mutex> lock(mu);
  auto it = cache.find(key);
  if (it == cache.end()) {
    const sim::Scenario w = warmup_scenario(sc);
    const sim::SimOutput out = sim::simulate(w);
    ToothErrorLearner learner(w.engine, w.wheel, params);
    const auto samples = sim::ideal_tooth_samples(out, w);
    for (std::size_t i = 0; i < samples.size(); ++i) {
      // Fuel cut-off flag from CAN as the daemon does (AngleStage::on_tooth).
      const EngineSignals sig = sim::signals_at(out, static_cast<double>(samples[i].t_ns) * 1e-9);
      learner.set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);
      learner.set_map(sig.map_pa, sig.map_valid);
      learner.set_spark(sig.spark_advance_deg, sig.spark_valid);
      learner.update(samples[i]);
    }
    LearnedTable t;
    t.ratio.resize(static_cast<std::size_t>(learner.teeth()));
    for (int p = 0; p < learner.teeth(); ++p) t.ratio[static_cast<std::size_t>(p)] = learner.width_ratio(p);
    t.cycles = learner.stats().cycles_used;
    t.low_orders = learner.low_orders_learned();
    it = cache.emplace(key, std::move(t)).first;
  }
  if (cycles) *cycles = it->second.cycles;
  if (low_orders) *low_orders = it->second.low_orders;
  return it->second.ratio;
}

ScenarioResult evaluate(const sim::Scenario& sc, const EvalOptions& opt) {
  return evaluate(sc, sim::simulate(sc), opt);
}

AnglePipelineConfig pipeline_config(const sim::Scenario& sc, const EvalOptions& opt) {
  AnglePipelineConfig cfg = opt.base;
  cfg.engine = opt.spec_engine ? *opt.spec_engine : sc.engine;
  cfg.wheel = sc.wheel;
  cfg.friction.prior_from_geometry = !opt.friction_prior;
  if (opt.friction_prior) cfg.friction.c = *opt.friction_prior;
  cfg.e_machine = opt.e_machine;
  return cfg;
}

namespace {

/// Applies the tooth table `opt` asks for (none, the true wheel, the learned one) to the samples' widths, and
/// scores its residual against the true width errors (the wheel's, not the jitter's) and of the edge angles
/// (cumulative width residual, mean removed): what the kinetic-energy windows see.
void apply_tooth_table(const sim::Scenario& sc, const sim::SimOutput& out, const EvalOptions& opt,
                       std::vector<ToothSample>& samples, ScenarioResult& r) {
  const int teeth = sc.wheel.teeth();
  if (static_cast<int>(out.tooth_error_rad.size()) != teeth) return;
  std::vector<double> ratio;
  if (opt.tooth_table == ToothTable::kLearned)
    ratio = learned_width_ratios(sc, opt.tooth_learn, &r.tooth_learn_cycles, &r.tooth_low_orders);
  const auto true_err = [&](int p) {
    return out.tooth_error_rad[static_cast<std::size_t>(p)] -
           out.tooth_error_rad[static_cast<std::size_t>((p + teeth - 1) % teeth)];
  };
  std::vector<double> nominal(static_cast<std::size_t>(teeth), 0.0);
  for (ToothSample& s : samples) {
    const int p = s.tooth % teeth;
    const auto pi = static_cast<std::size_t>(p);
    nominal[pi] = s.width_rad;
    if (opt.tooth_table == ToothTable::kTrue) {
      s.width_rad += true_err(p);
    } else if (opt.tooth_table == ToothTable::kLearned && ratio.size() == nominal.size()) {
      s.width_rad *= ratio[pi];
    }
  }
  std::vector<double> edge(static_cast<std::size_t>(teeth), 0.0);
  double ss = 0.0, cum = 0.0, mean_e = 0.0;
  for (int p = 0; p < teeth; ++p) {
    const auto pi = static_cast<std::size_t>(p);
    const double err = true_err(p);
    double used = 0.0;
    if (opt.tooth_table == ToothTable::kTrue) used = err;
    if (opt.tooth_table == ToothTable::kLearned && ratio.size() == nominal.size())
      used = (ratio[pi] - 1.0) * nominal[pi];
    ss += (used - err) * (used - err);
    cum += used - err;
    edge[pi] = cum;
    mean_e += cum / teeth;
  }
  r.tooth_resid_deg = std::sqrt(ss / teeth) / kDeg;
  double se = 0.0;
  for (double e : edge) se += (e - mean_e) * (e - mean_e);
  r.tooth_edge_resid_deg = std::sqrt(se / teeth) / kDeg;
}

/// Exact truth over the pipeline's own 720° windows: the energy form d(½Jθ̇²)/dθ = T_ind − T_fric − T_load
/// holds exactly in the simulator, so the true angle-mean of T_brake − T_load over [a, b] is ΔKE_true/(b −
/// a), with KE from the true edge speeds, averaged over the same ±window/2 as the estimator. Load and
/// friction are smooth and are integrated by the trapezoid rule over the edges.
class WindowTruth {
 public:
  WindowTruth(const sim::Scenario& sc, const sim::SimOutput& out, const AnglePipelineConfig& cfg) {
    const CrankKinematics kin(sc.engine);
    const std::size_t nt = out.teeth.size();
    abs_a_.resize(nt);
    ke_.resize(nt);
    cum_load_.assign(nt, 0.0);
    cum_fric_.assign(nt, 0.0);
    for (std::size_t i = 0; i < nt; ++i) {
      const sim::ToothTruth& t = out.teeth[i];
      abs_a_[i] = kFourPi * t.cycle + t.angle720_rad;
      ke_[i] = 0.5 * kin.inertia(t.angle720_rad - sc.engine.tdc_offset_rad) * t.speed_rad_s * t.speed_rad_s;
      if (i > 0) {
        const double da = abs_a_[i] - abs_a_[i - 1];
        cum_load_[i] = cum_load_[i - 1] + 0.5 * (t.t_load_nm + out.teeth[i - 1].t_load_nm) * da;
        cum_fric_[i] = cum_fric_[i - 1] + 0.5 * (t.t_fric_nm + out.teeth[i - 1].t_fric_nm) * da;
      }
    }
    half_w_ = 0.5 * cfg.energies.energy_window_deg * kDeg;
    // The pipeline's 720° balance averages KE over [b + w/2 − W, b + w/2) (energies.cycle_ke_window_deg = W,
    // or ±w/2 when 0): the truth uses the same window (an exact balance averaged over the same boundary
    // shifts).
    const double wide_w = cfg.energies.cycle_ke_window_deg * kDeg;
    lo_w_ = wide_w > 0.0 && wide_w < 2.0 * std::numbers::pi ? half_w_ - wide_w : -half_w_;
  }
  /// Mean load, friction and ΔKE/4π over [a_start, a_end] (wheel angle, absolute): NaN outside the run.
  [[nodiscard]] double load(double a0, double a1) const {
    return (interp(cum_load_, a1) - interp(cum_load_, a0)) / kFourPi;
  }
  [[nodiscard]] double fric(double a0, double a1) const {
    return (interp(cum_fric_, a1) - interp(cum_fric_, a0)) / kFourPi;
  }
  [[nodiscard]] double dke(double a0, double a1) const { return (ke_at(a1) - ke_at(a0)) / kFourPi; }

 private:
  [[nodiscard]] double interp(const std::vector<double>& cum, double a) const {
    const auto it = std::lower_bound(abs_a_.begin(), abs_a_.end(), a);
    if (it == abs_a_.begin() || it == abs_a_.end()) return std::nan("");
    const std::size_t j = static_cast<std::size_t>(it - abs_a_.begin());
    const double f = (a - abs_a_[j - 1]) / (abs_a_[j] - abs_a_[j - 1]);
    return cum[j - 1] + f * (cum[j] - cum[j - 1]);
  }
  [[nodiscard]] double ke_at(double a) const {
    auto it = std::lower_bound(abs_a_.begin(), abs_a_.end(), a + lo_w_);
    double sum = 0.0;
    int cnt = 0;
    for (; it != abs_a_.end() && *it <= a + half_w_; ++it) {
      sum += ke_[static_cast<std::size_t>(it - abs_a_.begin())];
      ++cnt;
    }
    return cnt > 0 ? sum / cnt : std::nan("");
  }
  std::vector<double> abs_a_, ke_, cum_load_, cum_fric_;
  double half_w_ = 0.0, lo_w_ = 0.0;
};

/// What the per-cycle loop of evaluate() carries from one cycle to the next.
struct EvalRun {
  std::set<std::pair<int, int>> true_misfires, found;
  int cycle_rows = 0, first_cycle = -1, last_cycle = -1;
  double prev_true = 0.0, prev_rpm = 0.0;
  bool have_prev = false;
  int transient_hold = 0;
  std::array<double, kMaxCylinders> imb_true_sum{};
  int imb_true_n = 0;
};

/// Misfire matching: the cylinder at firing position m fired at boundary m + |offset| of this window.
void match_misfires(const sim::Scenario& sc, const CycleOutput& o, double a_start, double offset, int cycle,
                    EvalRun& run, ScenarioResult& r) {
  if (o.cylinders.health == Health::kInvalidInput || run.cycle_rows < 2) return;
  const int n = sc.engine.cylinders;
  ++r.detection_cycles;
  if (o.cylinders.detection == MisfireDetection::kActive) ++r.detection_active;
  if (run.first_cycle < 0) run.first_cycle = cycle;
  run.last_cycle = cycle;
  for (int m = 0; m < n; ++m) {
    const int cyl = sc.engine.firing_order[static_cast<std::size_t>(m)];
    const double tdc_w = a_start + m * kFourPi / n - offset;
    const int tc = static_cast<int>(std::floor(tdc_w / kFourPi + 1e-9));
    if (!o.cylinders.misfire[static_cast<std::size_t>(cyl - 1)]) continue;
    if (run.true_misfires.count({tc, cyl})) {
      run.found.insert({tc, cyl});
    } else {
      ++r.misfires_false;
    }
  }
}

/// One cycle's estimates against the window truth (load, friction, ΔKE means); false outside the run.
bool make_row(const CycleOutput& o, const AnglePipeline& pipe, const WindowTruth& wt, double a_start,
              double a_end, CycleCompare& row) {
  row.speed_rpm = o.speed_mean_rad_s * 30.0 / std::numbers::pi;
  const double load_m = wt.load(a_start, a_end);
  const double fric_m = wt.fric(a_start, a_end);
  const double dke_m = wt.dke(a_start, a_end);
  if (!std::isfinite(load_m + fric_m + dke_m)) return false;
  row.brake = o.brake.torque_nm;
  row.brake_true = dke_m + load_m;
  row.indicated = o.indicated.torque_nm;
  row.indicated_true = dke_m + load_m + fric_m;
  row.friction = o.friction.torque_nm;
  row.friction_true = fric_m;
  row.load_rls = o.load_rls.torque_nm;
  row.load_star_true = load_m + fric_m;
  row.indicated_crank = o.indicated_crank.torque_nm;
  row.indicated_eso = o.indicated_eso.torque_nm;
  row.fused = o.fused.brake_nm;
  row.brake_sd = o.brake.uncertainty;
  row.indicated_sd = o.indicated.uncertainty;
  row.fused_sd = o.fused.sd_nm;
  row.friction_prior = pipe.friction().is_prior();
  row.quality = o.fused.quality;
  row.brake_valid = o.brake.health == Health::kValid;
  row.indicated_valid = o.indicated.health == Health::kValid;
  row.rls_valid = o.load_rls.health == Health::kValid;
  row.eso_valid = o.indicated_eso.health == Health::kValid;
  return true;
}

/// Marks the row transient (the true brake torque or speed moves between consecutive cycles; held 2 cycles)
/// and adds it to every score with the steady or transient tolerance.
void score_row(const CycleOutput& o, const EvalOptions& opt, CycleCompare& row, EvalRun& run,
               ScenarioResult& r) {
  if (run.have_prev && (std::fabs(row.brake_true - run.prev_true) > 1.5 ||
                        std::fabs(row.speed_rpm - run.prev_rpm) > 0.01 * run.prev_rpm)) {
    run.transient_hold = 2;
  }
  row.transient = run.transient_hold > 0;
  if (run.transient_hold > 0) --run.transient_hold;
  run.prev_true = row.brake_true;
  run.prev_rpm = row.speed_rpm;
  run.have_prev = true;
  const double pct = row.transient ? opt.transient_pct : opt.steady_pct;
  const double nm = row.transient ? opt.transient_nm : opt.steady_nm;
  if (row.brake_valid || opt.score_all_cycles) add(r.brake, row.brake, row.brake_true, pct, nm, row.brake_sd);
  if (row.indicated_valid || opt.score_all_cycles)
    add(r.indicated, row.indicated, row.indicated_true, pct, nm, row.indicated_sd);
  if (o.fused.quality != FusionQuality::kInvalid)
    add(r.fused, row.fused, row.brake_true, pct, nm, row.fused_sd);
  add(r.friction, row.friction, row.friction_true, pct, nm);
  if (row.rls_valid) {
    add(r.load_rls, row.load_rls, row.load_star_true, pct, nm);
    add(r.indicated_crank, row.indicated_crank, row.indicated_true, pct, nm);
    add(r.brake_crank, row.indicated_crank - row.friction, row.brake_true, pct, nm);
  }
  if (row.eso_valid) add(r.indicated_eso, row.indicated_eso, row.indicated_true, pct, nm);
  r.mean_rpm += row.speed_rpm;
}

/// True imbalance of cycle `c1` (firing cycles only): each cylinder's share of the mean, in %.
void add_true_imbalance(const sim::CycleTruth& c1, int n, EvalRun& run) {
  bool any_mis = false;
  double mean = 0.0;
  for (int j = 0; j < n; ++j) {
    any_mis = any_mis || c1.misfire[static_cast<std::size_t>(j)];
    mean += c1.cyl_ind_mean_nm[static_cast<std::size_t>(j)] / n;
  }
  if (any_mis || c1.fuel_cut || std::fabs(mean) <= 1.0) return;
  for (int j = 0; j < n; ++j) {
    run.imb_true_sum[static_cast<std::size_t>(j)] +=
        (c1.cyl_ind_mean_nm[static_cast<std::size_t>(j)] / mean - 1.0) * 100.0;
  }
  ++run.imb_true_n;
}

/// The run's totals: RMS of every score, imbalance against the truth, misfires, and what the pipeline
/// learned.
void finish_result(const AnglePipeline& pipe, int n, const EvalRun& run, ScenarioResult& r) {
  r.cycles = static_cast<int>(r.rows.size());
  if (r.cycles > 0) r.mean_rpm /= r.cycles;
  for (ErrorStats* s : {&r.brake, &r.indicated, &r.fused, &r.brake_crank, &r.indicated_crank,
                        &r.indicated_eso, &r.friction, &r.load_rls}) {
    finish(*s);
  }
  const CycleOutput& last = pipe.cycle_output();
  for (int j = 0; j < n; ++j) {
    const auto ji = static_cast<std::size_t>(j);
    r.imbalance_est[ji] = last.cylinders.imbalance_filtered_pct[ji];
    r.imbalance_true[ji] = run.imb_true_n > 0 ? run.imb_true_sum[ji] / run.imb_true_n : 0.0;
    r.imbalance_max_pp = std::max(r.imbalance_max_pp, std::fabs(r.imbalance_est[ji] - r.imbalance_true[ji]));
  }
  for (const auto& m : run.true_misfires) {
    if (run.first_cycle >= 0 && m.first >= run.first_cycle && m.first <= run.last_cycle) ++r.misfires_true;
  }
  r.misfires_found = static_cast<int>(run.found.size());
  r.friction_coefficients = pipe.friction().coefficients();
  r.idle_correction_nm = pipe.friction().idle_correction_nm();
  r.idle_rpm = pipe.friction().idle_speed_rpm();
  r.fuel_state = pipe.fuel_model().state();
  r.crank_err_var = pipe.crank_error_var();
  r.friction_observations = pipe.stats().friction_observations;
  r.stats = pipe.stats();
}

/// The CAN signals at `t_s` as the options leave them (all lost after can_lost_after_s, the load after
/// load_lost_after_s, no fuel cut-off flag).
EngineSignals eval_signals(const sim::SimOutput& out, const EvalOptions& opt, double t_s,
                           EngineSignals& last_sig) {
  EngineSignals sig;
  if (opt.can_lost_after_s >= 0.0 && t_s >= opt.can_lost_after_s) {
    sig = EngineSignals{};
    sig.t_ns = last_sig.t_ns;  // the store still knows when it last heard something; all values invalid
  } else {
    sig = sim::signals_at(out, t_s);
    last_sig = sig;
  }
  if (opt.load_lost_after_s >= 0.0 && t_s >= opt.load_lost_after_s) sig.load_torque_valid = false;
  if (opt.no_fuel_cutoff_flag) sig.fuel_cutoff_valid = false;
  return sig;
}

}  // namespace

ScenarioResult evaluate(const sim::Scenario& sc, const sim::SimOutput& out, const EvalOptions& opt) {
  const AnglePipelineConfig cfg = pipeline_config(sc, opt);
  AnglePipeline pipe(cfg);
  if (opt.friction) pipe.friction().import_coefficients(*opt.friction);
  if (opt.fuel_state) pipe.fuel_model().import_state(*opt.fuel_state);
  if (opt.crank_err_var) pipe.import_crank_error_var(*opt.crank_err_var);
  if (opt.idle_correction)
    pipe.friction().import_idle_correction((*opt.idle_correction)[0], (*opt.idle_correction)[1]);
  std::vector<ToothSample> samples = sim::ideal_tooth_samples(out, sc);
  ScenarioResult r;
  apply_tooth_table(sc, out, opt, samples, r);
  std::map<int, const sim::CycleTruth*> truth;
  for (const auto& c : out.cycles) truth[c.cycle] = &c;
  EvalRun run;
  for (const auto& c : out.cycles) {
    for (int j = 0; j < sc.engine.cylinders; ++j) {
      if (c.misfire[static_cast<std::size_t>(j)]) run.true_misfires.insert({c.cycle, j + 1});
    }
  }
  const WindowTruth wt(sc, out, cfg);
  r.name = sc.name;
  const int n = sc.engine.cylinders;
  const double offset = cfg.energies.segment_offset_deg * kDeg;
  const double b0_wheel = wrap4pi(sc.engine.tdc_offset_rad + offset);  // boundary 0 in wheel angle
  EngineSignals last_sig;
  for (std::size_t i = 0; i < samples.size() && i < out.teeth.size(); ++i) {
    const ToothSample& s = samples[i];
    const double t_s = static_cast<double>(s.t_ns) * 1e-9;
    const EngineSignals sig = eval_signals(out, opt, t_s, last_sig);
    const std::uint8_t ready = pipe.on_tooth(s, sig);
    if (!(ready & AnglePipeline::kCycleReady)) continue;
    const CycleOutput& o = pipe.cycle_output();
    const sim::ToothTruth& tt = out.teeth[i];
    double a_end = kFourPi * tt.cycle + b0_wheel;
    if (b0_wheel > tt.angle720_rad + 1e-9) a_end -= kFourPi;
    const double a_start = a_end - kFourPi;
    const int j0 = static_cast<int>(std::floor(a_start / kFourPi));
    if (!truth.count(j0) || !truth.count(j0 + 1)) continue;
    ++run.cycle_rows;
    match_misfires(sc, o, a_start, offset, j0 + 1, run, r);
    if (run.cycle_rows <= opt.skip_cycles) continue;
    CycleCompare row;
    row.t_s = t_s;
    if (!make_row(o, pipe, wt, a_start, a_end, row)) continue;
    score_row(o, opt, row, run, r);
    add_true_imbalance(*truth[j0 + 1], n, run);
    r.rows.push_back(row);
  }
  finish_result(pipe, n, run, r);
  return r;
}

namespace {
EvalOptions bed_options(const sim::BedEngine& e, const EvalOptions& options) {
  EvalOptions o = options;
  o.spec_engine = e.spec;
  o.friction_prior.reset();  // generic correlation from the spec-sheet displacement
  o.friction.reset();
  o.idle_correction.reset();
  o.score_all_cycles = true;
  o.can_lost_after_s = -1.0;
  o.load_lost_after_s = -1.0;
  return o;
}
}  // namespace

BedResult evaluate_bed_engine(const sim::BedEngine& e, const EvalOptions& options, bool short_run) {
  BedResult b;
  b.engine = e.name;
  b.report = e.report;
  EvalOptions o = bed_options(e, options);
  b.learn = evaluate(sim::bed_learning_run(e), o);
  // Carry the learned state into the evaluated recording (as the daemon's --state-dir does).
  if (b.learn.friction_observations > 0) o.friction = b.learn.friction_coefficients;
  if (b.learn.idle_rpm > 0.0)
    o.idle_correction = std::array<double, 2>{b.learn.idle_correction_nm, b.learn.idle_rpm};
  o.fuel_state = b.learn.fuel_state;
  o.crank_err_var = b.learn.crank_err_var;
  const sim::Scenario sc = sim::bed_eval_run(e, short_run);
  const sim::SimOutput out = sim::simulate(sc);
  b.with_load = evaluate(sc, out, o);
  o.load_lost_after_s = 0.0;
  b.without_load = evaluate(sc, out, o);
  return b;
}

namespace {
EMachineParams sole_machine(double ratio) {
  EMachineParams p;
  p.bound = true;
  p.ratio = ratio;
  p.sole_load = true;
  return p;
}
sim::Scenario with_machine(sim::Scenario s, double ratio) {
  s.e_machine.present = true;
  s.e_machine.ratio = ratio;
  return s;
}
}  // namespace

BedMachineResult evaluate_bed_e_machine(const sim::BedEngine& e, const EvalOptions& options, bool short_run,
                                        double ratio) {
  BedMachineResult b;
  b.engine = e.name;
  EvalOptions o = bed_options(e, options);
  o.load_lost_after_s = 0.0;  // no dynamometer: the machine is the known load
  o.e_machine = sole_machine(ratio);
  b.learn = evaluate(with_machine(sim::bed_learning_run(e), ratio), o);
  if (b.learn.friction_observations > 0) o.friction = b.learn.friction_coefficients;
  if (b.learn.idle_rpm > 0.0)
    o.idle_correction = std::array<double, 2>{b.learn.idle_correction_nm, b.learn.idle_rpm};
  o.fuel_state = b.learn.fuel_state;
  o.crank_err_var = b.learn.crank_err_var;
  const sim::Scenario sc = with_machine(sim::bed_eval_run(e, short_run), ratio);
  const sim::SimOutput out = sim::simulate(sc);
  b.with_machine = evaluate(sc, out, o);
  o.e_machine = EMachineParams{};  // control: the machine's torque is on CAN but not bound
  b.control = evaluate(sc, out, o);
  return b;
}

BedMotoringResult evaluate_bed_motoring(const sim::BedEngine& e, const EvalOptions& options, bool short_run,
                                        double ratio) {
  BedMotoringResult b;
  b.engine = e.name;
  EvalOptions o = bed_options(e, options);
  o.load_lost_after_s = 0.0;
  o.steady_pct = o.transient_pct = 10.0;  // friction target: 10 % or 2 N m
  o.steady_nm = o.transient_nm = 2.0;
  o.e_machine = sole_machine(ratio);
  b.motoring = evaluate(with_machine(sim::bed_motoring_run(e), ratio), o);
  // Scored on the evaluated recording with neither load signal nor machine bound: nothing is learned there.
  o.e_machine = EMachineParams{};
  const sim::Scenario sc = sim::bed_eval_run(e, short_run);
  const sim::SimOutput out = sim::simulate(sc);
  b.prior = evaluate(sc, out, o);
  if (b.motoring.friction_observations > 0) o.friction = b.motoring.friction_coefficients;
  b.learned = evaluate(sc, out, o);
  return b;
}

namespace {
BedFuelRun score_fuel(const ScenarioResult& r) {
  BedFuelRun f;
  double se = 0.0, st = 0.0;
  for (const CycleCompare& w : r.rows) {
    ++f.cycles;
    if (w.quality == FusionQuality::kInvalid) continue;
    ++f.published;
    f.prior_only += w.quality == FusionQuality::kPriorOnly ? 1 : 0;
    const double err = w.fused - w.brake_true;
    f.pass += std::fabs(err) <= std::max(0.08 * std::fabs(w.brake_true), 5.0) ? 1 : 0;
    f.covered += std::fabs(err) <= w.fused_sd ? 1 : 0;
    f.covered2 += std::fabs(err) <= 2.0 * w.fused_sd ? 1 : 0;
    se += err * err;
    st += w.brake_true * w.brake_true;
    f.bias_nm += err;
  }
  f.rows = r.rows;
  if (f.published > 0) {
    f.rms_nm = std::sqrt(se / f.published);
    f.rms_pct = st > 0.0 ? 100.0 * std::sqrt(se / st) : 0.0;
    f.bias_nm /= f.published;
  }
  f.references = r.fuel_state.references;
  for (int i = 0; i < kFuelCells; ++i)
    if (r.fuel_state.cells[static_cast<std::size_t>(i)] >= FuelTorqueParams{}.cell_min_references)
      f.cells = static_cast<std::uint16_t>(f.cells | (1u << i));
  return f;
}
}  // namespace

BedFuelResult evaluate_bed_fuel(const sim::BedEngine& e, const EvalOptions& options, bool short_run) {
  BedFuelResult b;
  b.engine = e.name;
  EvalOptions o = bed_options(e, options);
  const sim::Scenario sc = sim::bed_eval_run(e, short_run);
  const sim::SimOutput out = sim::simulate(sc);
  // Never taught: the generic friction prior, the fuel model's prior, no load signal anywhere.
  EvalOptions never = o;
  never.load_lost_after_s = 0.0;
  b.never = score_fuel(evaluate(sc, out, never));
  b.never.references = 0;
  // Taught at one operating point (plus overrun and idle) with the load signal, evaluated without it.
  const ScenarioResult learn = evaluate(sim::bed_one_point_learning_run(e), o);
  if (learn.friction_observations > 0) o.friction = learn.friction_coefficients;
  if (learn.idle_rpm > 0.0)
    o.idle_correction = std::array<double, 2>{learn.idle_correction_nm, learn.idle_rpm};
  o.fuel_state = learn.fuel_state;
  o.crank_err_var = learn.crank_err_var;
  const ScenarioResult with = evaluate(sc, out, o);
  b.with_load_rms_nm = with.fused.rms_nm;
  o.load_lost_after_s = 0.0;
  b.one_point = score_fuel(evaluate(sc, out, o));
  b.one_point.references = learn.fuel_state.references;
  b.one_point.cells = score_fuel(learn).cells;
  return b;
}

std::array<double, 4> learn_friction(const EvalOptions& options) {
  // The daemon keeps learning over its life and persists the coefficients; here: the fuel_cut coast-down from
  // the prior, then the demo run (whose fuel cut-off starts at 3500 rpm) continuing from the persisted
  // coefficients.
  EvalOptions o = options;
  o.friction.reset();
  o.can_lost_after_s = -1.0;  // learning runs see CAN
  std::array<double, 4> c{};
  for (const char* name : {"fuel_cut", "demo"}) {
    const ScenarioResult r = evaluate(sim::scenario_by_name(name), o);
    c = r.friction_coefficients;
    o.friction = c;
  }
  return c;
}

}  // namespace torqued::eval
