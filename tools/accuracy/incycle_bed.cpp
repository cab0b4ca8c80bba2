#include "incycle_bed.hpp"

#include <cmath>
#include <numbers>
#include <unordered_map>

#include "angle_pipeline.hpp"
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
}  // namespace

InCycleBedResult evaluate_incycle_fresh(const sim::BedEngine& engine, const EvalOptions& opt,
                                        bool short_run) {
  InCycleBedResult r;
  r.engine = engine.name;
  r.report = engine.report;
  std::vector<std::pair<double, double>> steady;
  const sim::Scenario sc = sim::bed_firing_start_run(engine, short_run, &steady);
  const sim::SimOutput out = sim::simulate(sc);
  r.duration_s = sc.duration_s;
  r.score_from_s = steady.empty() ? 0.0 : steady.front().first;
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
  const auto scored = [&steady](double t) {
    for (const auto& [a, b] : steady)
      if (t >= a && t < b) return true;
    return false;
  };
  std::vector<double> ek, tk, ef, tf;
  std::vector<int> ck, cf;
  int prev_tooth = -1;
  for (std::size_t i = 0; i < samples.size() && i < out.teeth.size(); ++i) {
    ToothSample s = samples[i];
    const auto p = static_cast<std::size_t>(s.tooth % teeth);
    nominal[p] = s.width_rad;
    const double t_s = static_cast<double>(s.t_ns) * 1e-9;
    const EngineSignals sig = sim::signals_at(out, t_s);
    if (learned) {  // the chain's order: learner first, with nominal widths
      learner.set_fuel_cutoff(sig.fuel_cutoff_valid && sig.fuel_cutoff);
      learner.set_map(sig.map_pa, sig.map_valid);
      learner.update(s);
      if (prev_tooth >= 0 && s.tooth < prev_tooth && learner.ready()) {  // cycle end: table applied
        for (int q = 0; q < teeth; ++q) ratio[static_cast<std::size_t>(q)] = learner.width_ratio(q);
        pipe.set_wheel_learned(true);
        if (r.ready_at_s < 0.0) r.ready_at_s = t_s;
      }
      prev_tooth = s.tooth;
    }
    s.width_rad *= ratio[p];
    pipe.on_tooth(s, sig);
    const ToothOutput& to = pipe.tooth_output();
    if (to.kalman_ind.health == Health::kValid) {
      const auto it = index.find(to.kalman_ind.t_ns);
      if (it != index.end() && scored(static_cast<double>(to.kalman_ind.t_ns) * 1e-9)) {
        ek.push_back(to.kalman_ind.torque_nm);
        tk.push_back(out.teeth[it->second].t_ind_nm);
        ck.push_back(out.teeth[it->second].cycle);
      }
    }
    if (to.fourier_ind.health == Health::kValid && scored(t_s)) {
      ef.push_back(to.fourier_ind.torque_nm);
      tf.push_back(out.teeth[i].t_ind_nm);
      cf.push_back(out.teeth[i].cycle);
    }
  }
  const double step = 360.0 / sc.wheel.positions;
  r.kalman = incycle_stats(ek, tk, ck, step);
  r.fourier = incycle_stats(ef, tf, cf, step);
  r.tooth_edge_resid_deg = edge_residual_deg(out, ratio, nominal);
  r.cycles_used = learner.stats().cycles_used;
  r.cycles_cutoff = learner.stats().cycles_cutoff;
  r.low_orders = learner.low_orders_learned();
  r.quality = learned ? learner.quality() : ToothLearnQuality::kNone;
  for (const ToothOrderId& id : learner.order_ids()) r.orders += order_letter(id.source);
  return r;
}

}  // namespace torqued::eval
