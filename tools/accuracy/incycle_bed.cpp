#include "incycle_bed.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <unordered_map>

#include "angle_pipeline.hpp"
#include "burn_phase_learner.hpp"
#include "tooth_error_learner.hpp"

namespace torqued::eval {

namespace {
char order_letter(ToothOrderSource s) {
  switch (s) {
    case ToothOrderSource::kHeld:
      return 'h';
    case ToothOrderSource::kOverrun:
      return 'o';
    case ToothOrderSource::kOverrunSpeeds:
      return 'O';
    case ToothOrderSource::kSpeeds:
      return 's';
    case ToothOrderSource::kFiring:
      return 'f';
  }
  return '?';
}

/// Edge-angle residual (deg RMS, mean removed) of the width ratios `ratio` against the true wheel.
double edge_residual_deg(const sim::SimOutput& out, const std::vector<double>& ratio,
                         const std::vector<double>& nominal) {
  const auto teeth = ratio.size();
  if (out.tooth_error_rad.size() != teeth || teeth == 0) return 0.0;
  std::vector<double> edge(teeth, 0.0);
  double cum = 0.0, mean = 0.0;
  for (std::size_t p = 0; p < teeth; ++p) {
    const double true_err = out.tooth_error_rad[p] - out.tooth_error_rad[(p + teeth - 1) % teeth];
    cum += (ratio[p] - 1.0) * nominal[p] - true_err;
    edge[p] = cum;
    mean += cum / static_cast<double>(teeth);
  }
  double se = 0.0;
  for (double e : edge) se += (e - mean) * (e - mean);
  return std::sqrt(se / static_cast<double>(teeth)) * 180.0 / std::numbers::pi;
}
/// One scored window (several [from, to) spans) and what it collected.
struct Window {
  std::vector<std::pair<double, double>> spans;
  std::vector<double> ek, tk, sk, tek, ef, tf;
  std::vector<int> ck, cf;
  [[nodiscard]] bool holds(double t) const {
    for (const auto& [a, b] : spans)
      if (t >= a && t < b) return true;
    return false;
  }
};

/// Share (%) of the samples whose |estimate − truth| is within the claimed 1σ.
double coverage_pct(const Window& w) {
  if (w.ek.empty()) return 0.0;
  std::size_t in = 0;
  for (std::size_t i = 0; i < w.ek.size(); ++i) in += std::fabs(w.ek[i] - w.tk[i]) <= w.sk[i] ? 1 : 0;
  return 100.0 * static_cast<double>(in) / static_cast<double>(w.ek.size());
}

/// RMS over the window's cycles of the per-cycle mean error (the slow, load-like part), and the worst RMS
/// over 1 s spans, both in % of the window's mean per-cycle p2p (`p2p` from incycle_stats()).
void slow_and_worst(const Window& w, const InCycleStats& st, InCycleRegime& g) {
  if (st.n == 0 || w.ek.empty()) return;
  const double p2p = st.p2p_nm;
  double s_cyc = 0.0, acc = 0.0;
  int n_cyc = 0, n_in = 0;
  for (std::size_t i = 0; i <= w.ek.size(); ++i) {
    if (i == w.ek.size() || (i > 0 && w.ck[i] != w.ck[i - 1])) {
      if (n_in > 0) {
        s_cyc += (acc / n_in) * (acc / n_in);
        ++n_cyc;
      }
      acc = 0.0;
      n_in = 0;
      if (i == w.ek.size()) break;
    }
    acc += w.ek[i] - w.tk[i];
    ++n_in;
  }
  g.kalman_slow_pct = n_cyc > 0 ? 100.0 * std::sqrt(s_cyc / n_cyc) / p2p : 0.0;
  double se = 0.0;
  std::size_t n = 0, start = 0;
  for (std::size_t i = 0; i <= w.ek.size(); ++i) {
    if (i == w.ek.size() || w.tek[i] - w.tek[start] >= 1.0) {
      if (n > 0) g.kalman_worst_s_pct = std::max(g.kalman_worst_s_pct, 100.0 * std::sqrt(se / n) / p2p);
      se = 0.0;
      n = 0;
      start = i;
      if (i == w.ek.size()) break;
    }
    se += (w.ek[i] - w.tk[i]) * (w.ek[i] - w.tk[i]);
    ++n;
  }
}

/// Per-tooth diagnostics of run_fresh() (EvalOptions::incycle_dump / incycle_regimes_dump). Two placements:
/// the inputs and the filter step of the tooth just measured (the gas model's ripple handed to the observers
/// for the coming step, MAP, spark, the centroid, the Kalman's innovation ν and its gain at the output state
/// x2(k−d)), and the Kalman's smoothed estimate with its parts (the model ripple and extended load inside it,
/// its claimed 1σ) at the tooth it describes, d teeth back.
struct ToothDump {
  std::vector<double> ripple, map, spark, centroid, innov, gain_out;  // at the tooth measured
  std::vector<double> kalman, model_out, load_star, sigma;            // at the tooth described
  void resize(std::size_t n) {
    for (auto* v : {&ripple, &map, &spark, &centroid, &innov, &gain_out}) v->assign(n, 0.0);
    for (auto* v : {&kalman, &model_out, &load_star, &sigma})
      v->assign(n, std::numeric_limits<double>::quiet_NaN());
  }
  /// Tooth `i` was just handed to `pipe`; `at` is the index of the tooth its Kalman estimate describes.
  void record(std::size_t i, const AnglePipeline& pipe, const EngineSignals& sig, std::size_t at,
              int output_state) {
    ripple[i] = pipe.last_ripple_nm();
    map[i] = sig.map_pa;
    spark[i] = sig.spark_advance_deg;
    centroid[i] = pipe.ripple_centroid_deg();
    const ChauvinKalman& k = pipe.kalman();
    innov[i] = k.last_innovation();
    gain_out[i] = k.last_gain()(output_state);
    const TorqueEstimate& e = pipe.tooth_output().kalman_ind;
    if (e.health != Health::kValid || at >= kalman.size()) return;
    kalman[at] = e.torque_nm;
    model_out[at] = k.output_model_nm();
    load_star[at] = k.extended_load_nm();
    sigma[at] = e.uncertainty;
  }
};

/// Bit j set: window j holds `t` (the regimes' transient and cut-off windows overlap).
int windows_holding(const std::vector<Window>& windows, double t) {
  int bits = 0;
  for (std::size_t j = 0; j < windows.size(); ++j)
    if (windows[j].holds(t)) bits |= 1 << j;
  return bits;
}

/// Writes `d` with the simulator's truth per tooth as CSV (`scored`: bit mask of the windows holding the
/// tooth: 1 the fresh start's, or 1 transient | 2 cut-off for the regimes; 0 none). docs/eval.md lists the
/// columns.
void write_dump(const std::string& path, const sim::SimOutput& out, const ToothDump& d,
                const std::vector<Window>& windows, int cylinders) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return;
  std::fprintf(f,
               "t_s,cycle,tooth,angle720_deg,speed_rpm,t_ind_nm,t_mass_nm,ripple_nm,kalman_nm,map_pa,spark_"
               "deg,centroid_deg,scored");
  for (int c = 0; c < cylinders; ++c) std::fprintf(f, ",t_cyl%d_nm", c + 1);
  std::fprintf(f, ",kalman_model_nm,kalman_load_nm,kalman_sd_nm,innov_rad2_s2,gain_out_nm_s2_rad2\n");
  for (std::size_t i = 0; i < d.ripple.size(); ++i) {
    const sim::ToothTruth& t = out.teeth[i];
    std::fprintf(f, "%.7f,%d,%d,%.4f,%.3f,%.4f,%.4f,%.4f,%.4f,%.1f,%.2f,%.3f,%d", t.t_s, t.cycle, t.tooth,
                 t.angle720_rad * 180.0 / std::numbers::pi, t.speed_rad_s * 30.0 / std::numbers::pi,
                 t.t_ind_nm, t.t_mass_nm, d.ripple[i], d.kalman[i], d.map[i], d.spark[i], d.centroid[i],
                 windows_holding(windows, t.t_s));
    for (int c = 0; c < cylinders; ++c) std::fprintf(f, ",%.4f", t.t_ind_cyl_nm[static_cast<std::size_t>(c)]);
    std::fprintf(f, ",%.4f,%.4f,%.4f,%.6g,%.6g\n", d.model_out[i], d.load_star[i], d.sigma[i], d.innov[i],
                 d.gain_out[i]);
  }
  std::fclose(f);
}

/// What the learner ended with (table quality, counters, orders, edge residual).
struct LearnSummary {
  double ready_at_s = -1.0, edge_resid_deg = 0.0;
  std::uint64_t cycles_used = 0, cycles_cutoff = 0;
  bool low_orders = false;
  ToothLearnQuality quality = ToothLearnQuality::kNone;
  std::string orders;
  BurnPhaseSummary burn;
  Window early;  ///< the kEarlyWindowS after the table was first applied (the young table's phase)
};

/// Length of the early window after ready (s): the young wheel table's phase, where the demo's loss sits.
constexpr double kEarlyWindowS = 8.0;

/// Collects the pipeline's in-cycle outputs of this tooth into `w` when it holds them.
void collect(Window& w, const ToothOutput& to, const sim::SimOutput& out,
             const std::unordered_map<std::int64_t, std::size_t>& index, std::size_t i, double t_s) {
  if (to.kalman_ind.health == Health::kValid) {
    const auto it = index.find(to.kalman_ind.t_ns);
    if (it != index.end() && w.holds(static_cast<double>(to.kalman_ind.t_ns) * 1e-9)) {
      w.ek.push_back(to.kalman_ind.torque_nm);
      w.tk.push_back(out.teeth[it->second].t_ind_nm);
      w.ck.push_back(out.teeth[it->second].cycle);
      w.sk.push_back(to.kalman_ind.uncertainty);
      w.tek.push_back(static_cast<double>(to.kalman_ind.t_ns) * 1e-9);
    }
  }
  if (to.fourier_ind.health == Health::kValid && w.holds(t_s)) {
    w.ef.push_back(to.fourier_ind.torque_nm);
    w.tf.push_back(out.teeth[i].t_ind_nm);
    w.cf.push_back(out.teeth[i].cycle);
  }
}

/// The daemon's angle chain on `sc` from a fresh start (tooth learner empty, its table applied at each
/// cycle end), the in-cycle outputs collected into `windows`.
/// `dump_path`: where to write the per-tooth dump (empty: none).
LearnSummary run_fresh(const sim::BedEngine& engine, const sim::Scenario& sc, const sim::SimOutput& out,
                       const EvalOptions& opt, std::vector<Window>& windows, const std::string& dump_path) {
  EvalOptions o = opt;
  o.spec_engine = engine.spec;
  o.friction_prior.reset();  // a fresh daemon: the generic friction correlation from the spec sheet
  AnglePipeline pipe(pipeline_config(sc, o));
  if (opt.friction) pipe.friction().import_coefficients(*opt.friction);
  ToothErrorLearner learner(engine.spec, sc.wheel, opt.tooth_learn);
  const bool learned = opt.tooth_table == ToothTable::kLearned;
  pipe.set_wheel_learned(!learned);
  std::vector<ToothSample> samples = sim::ideal_tooth_samples(out, sc);
  const int teeth = sc.wheel.teeth();
  const auto nt = static_cast<std::size_t>(teeth);
  std::vector<double> ratio(nt, 1.0), nominal(nt, 0.0);
  if (opt.tooth_table == ToothTable::kTrue && out.tooth_error_rad.size() == nt) {
    for (const ToothSample& s : samples) nominal[static_cast<std::size_t>(s.tooth % teeth)] = s.width_rad;
    for (std::size_t p = 0; p < nt; ++p)
      ratio[p] = 1.0 + (out.tooth_error_rad[p] - out.tooth_error_rad[(p + nt - 1) % nt]) / nominal[p];
  }
  std::unordered_map<std::int64_t, std::size_t> index;
  for (std::size_t i = 0; i < samples.size(); ++i) index[samples[i].t_ns] = i;
  LearnSummary r;
  ToothDump dump;
  const bool dumping = !dump_path.empty() && !windows.empty();
  if (dumping) dump.resize(std::min(samples.size(), out.teeth.size()));
  const int output_state = ChauvinKalman::kTorqueState + pipe.config().kalman.smoother_lag;
  int prev_tooth = -1, prev_burn_tooth = -1;
  // The chain's feedback (6) (chain/angle_chain.cpp): the burn-phasing learner after the pipeline, its offset
  // applied at the cycle end.
  const KalmanParams& kp = pipe.config().kalman;
  std::optional<BurnPhaseLearner> burn;
  if (pipe.config().run_kalman && kp.gas_model && kp.burn_phase.learn)
    burn.emplace(engine.spec, sc.wheel, kp.burn_phase);
  for (std::size_t i = 0; i < samples.size() && i < out.teeth.size(); ++i) {
    ToothSample s = samples[i];
    const auto p = static_cast<std::size_t>(s.tooth % teeth);
    nominal[p] = s.width_rad;
    const double t_s = static_cast<double>(s.t_ns) * 1e-9;
    const EngineSignals sig = sim::signals_at(out, t_s);
    if (learned) {  // the chain's order: learner first, with nominal widths
      learner.set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);
      learner.set_map(sig.map_pa, sig.map_valid);
      learner.set_spark(sig.spark_advance_deg, sig.spark_valid);
      learner.update(s);
      if (prev_tooth >= 0 && s.tooth < prev_tooth && learner.ready()) {  // cycle end: table applied
        for (int q = 0; q < teeth; ++q) ratio[static_cast<std::size_t>(q)] = learner.width_ratio(q);
        pipe.set_wheel_learned(true);
        if (opt.tooth_learn.incycle_sd) pipe.set_wheel_table_var(wheel_table_accel_var(learner.order_ids()));
        if (r.ready_at_s < 0.0) {
          r.ready_at_s = t_s;
          r.early.spans = {{t_s, t_s + kEarlyWindowS}};
        }
      }
      prev_tooth = s.tooth;
    }
    s.width_rad *= ratio[p];
    pipe.on_tooth(s, sig);
    const ToothOutput& to = pipe.tooth_output();
    if (burn) {
      const ChauvinKalman& kf = pipe.kalman();
      burn->set_signals(sig.map_valid, sig.spark_valid, sig.fuel_cutoff_valid && sig.fuel_cutoff);
      burn->update(kf.estimate_tooth(), kf.estimate().torque_nm, kf.output_model_nm(),
                   to.kalman_ind.health == Health::kValid && kf.model_active());
      if (prev_burn_tooth >= 0 && s.tooth < prev_burn_tooth && burn->end_cycle())
        pipe.set_burn_offset_deg(burn->offset_deg());
      prev_burn_tooth = s.tooth;
    }
    if (dumping) {
      const auto it = index.find(to.kalman_ind.t_ns);
      dump.record(i, pipe, sig, it != index.end() ? it->second : dump.kalman.size(), output_state);
    }
    for (Window& w : windows) collect(w, to, out, index, i, t_s);
    collect(r.early, to, out, index, i, t_s);
  }
  if (dumping) write_dump(dump_path, out, dump, windows, sc.engine.cylinders);
  r.edge_resid_deg = edge_residual_deg(out, ratio, nominal);
  r.cycles_used = learner.stats().cycles_used;
  r.cycles_cutoff = learner.stats().cycles_cutoff;
  r.low_orders = learner.low_orders_learned();
  r.quality = learned ? learner.quality() : ToothLearnQuality::kNone;
  for (const ToothOrderId& id : learner.order_ids()) r.orders += order_letter(id.source);
  if (burn) {
    r.burn.on = true;
    r.burn.offset_deg = burn->offset_deg();
    r.burn.stats = burn->stats();
  }
  return r;
}

InCycleRegime score(const Window& w, double step_deg) {
  InCycleRegime g;
  g.kalman = incycle_stats(w.ek, w.tk, w.ck, step_deg);
  g.fourier = incycle_stats(w.ef, w.tf, w.cf, step_deg);
  g.kalman_cover_pct = coverage_pct(w);
  slow_and_worst(w, g.kalman, g);
  return g;
}
}  // namespace

InCycleBedResult evaluate_incycle_fresh(const sim::BedEngine& engine, const EvalOptions& opt,
                                        bool short_run) {
  InCycleBedResult r;
  r.engine = engine.name;
  r.report = engine.report;
  std::vector<Window> windows(1);
  const sim::Scenario sc = sim::bed_firing_start_run(engine, short_run, &windows[0].spans);
  const sim::SimOutput out = sim::simulate(sc);
  r.duration_s = sc.duration_s;
  r.score_from_s = windows[0].spans.empty() ? 0.0 : windows[0].spans.front().first;
  const LearnSummary l = run_fresh(engine, sc, out, opt, windows, opt.incycle_dump);
  const InCycleRegime g = score(windows[0], 360.0 / sc.wheel.positions);
  r.kalman = g.kalman;
  r.fourier = g.fourier;
  r.ready_at_s = l.ready_at_s;
  r.tooth_edge_resid_deg = l.edge_resid_deg;
  r.cycles_used = l.cycles_used;
  r.cycles_cutoff = l.cycles_cutoff;
  r.low_orders = l.low_orders;
  r.quality = l.quality;
  r.orders = l.orders;
  r.burn = l.burn;
  r.early = score(l.early, 360.0 / sc.wheel.positions);
  return r;
}

InCycleRegimesResult evaluate_incycle_regimes(const sim::BedEngine& engine, const EvalOptions& opt) {
  InCycleRegimesResult r;
  r.engine = engine.name;
  r.report = engine.report;
  std::vector<Window> windows(2);
  windows[0].spans.resize(1);
  windows[1].spans.resize(1);
  const sim::Scenario sc = sim::bed_incycle_regimes_run(engine, &windows[0].spans[0], &windows[1].spans[0]);
  const sim::SimOutput out = sim::simulate(sc);
  const LearnSummary l = run_fresh(engine, sc, out, opt, windows, opt.incycle_regimes_dump);
  const double step = 360.0 / sc.wheel.positions;
  r.transient = score(windows[0], step);
  r.cutoff = score(windows[1], step);
  r.ready_at_s = l.ready_at_s;
  r.quality = l.quality;
  r.burn = l.burn;
  return r;
}

InCycleRampResult evaluate_incycle_ramp(const sim::BedEngine& engine, const EvalOptions& opt,
                                        const std::string& dump_path) {
  InCycleRampResult r;
  r.engine = engine.name;
  r.report = engine.report;
  std::vector<Window> windows(1);
  windows[0].spans.resize(1);
  const sim::Scenario sc = sim::bed_ramp_start_run(engine, &windows[0].spans[0]);
  const sim::SimOutput out = sim::simulate(sc);
  const LearnSummary l = run_fresh(engine, sc, out, opt, windows, dump_path);
  r.ramp = score(windows[0], 360.0 / sc.wheel.positions);
  r.ready_at_s = l.ready_at_s;
  r.quality = l.quality;
  r.burn = l.burn;
  return r;
}

}  // namespace torqued::eval
