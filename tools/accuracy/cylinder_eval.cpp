#include "cylinder_eval.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <unordered_map>

#include "angle_pipeline.hpp"

namespace torqued::eval {

namespace {

sim::Scenario steady(const std::string& name, double rpm, double map_kpa, std::uint64_t seed) {
  sim::Scenario s;
  s.name = name;
  s.seed = seed;
  s.duration_s = 2.0;
  s.speed_rpm = {{0.0, rpm}};
  s.map_target_kpa = {{0.0, map_kpa}};
  return s;
}

/// Runs the angle pipeline with the learned tooth table and compares its per-tooth Kalman and Fourier
/// indicated torque (where valid, after `skip_cycles`) with the true indicated torque at the edge each refers
/// to.
void evaluate_incycle(const sim::Scenario& sc, const sim::SimOutput& out, const EvalOptions& opt,
                      CylinderCaseResult& r) {
  AnglePipeline pipe(pipeline_config(sc, opt));
  if (opt.friction) pipe.friction().import_coefficients(*opt.friction);
  std::vector<ToothSample> samples = sim::ideal_tooth_samples(out, sc);
  const int teeth = sc.wheel.teeth();
  // The tooth table of the options, as evaluate() uses it (--true-tooth-errors / --raw-teeth apply here too).
  if (opt.tooth_table == ToothTable::kTrue && static_cast<int>(out.tooth_error_rad.size()) == teeth) {
    for (ToothSample& s : samples) {
      const int p = s.tooth % teeth;
      s.width_rad += out.tooth_error_rad[static_cast<std::size_t>(p)] -
                     out.tooth_error_rad[static_cast<std::size_t>((p + teeth - 1) % teeth)];
    }
  } else if (opt.tooth_table == ToothTable::kLearned) {
    const std::vector<double> ratio = learned_width_ratios(sc, opt.tooth_learn);
    if (static_cast<int>(ratio.size()) == teeth) {
      for (ToothSample& s : samples) s.width_rad *= ratio[static_cast<std::size_t>(s.tooth % teeth)];
    }
  }
  std::unordered_map<std::int64_t, std::size_t> index;
  for (std::size_t i = 0; i < samples.size(); ++i) index[samples[i].t_ns] = i;
  std::vector<double> ek, tk, ef, tf;
  std::vector<int> ck, cf;
  const int first_cycle = out.teeth.empty() ? 0 : out.teeth.front().cycle + opt.skip_cycles;
  for (std::size_t i = 0; i < samples.size() && i < out.teeth.size(); ++i) {
    const double t_s = static_cast<double>(samples[i].t_ns) * 1e-9;
    pipe.on_tooth(samples[i], sim::signals_at(out, t_s));
    if (out.teeth[i].cycle < first_cycle) continue;
    const ToothOutput& o = pipe.tooth_output();
    if (o.kalman_ind.health == Health::kValid) {
      const auto it = index.find(o.kalman_ind.t_ns);
      if (it != index.end()) {
        ek.push_back(o.kalman_ind.torque_nm);
        tk.push_back(out.teeth[it->second].t_ind_nm);
        ck.push_back(out.teeth[it->second].cycle);
      }
    }
    if (o.fourier_ind.health == Health::kValid) {
      ef.push_back(o.fourier_ind.torque_nm);
      tf.push_back(out.teeth[i].t_ind_nm);
      cf.push_back(out.teeth[i].cycle);
    }
  }
  const double step = 360.0 / sc.wheel.positions;
  r.kalman = incycle_stats(ek, tk, ck, step);
  r.fourier = incycle_stats(ef, tf, cf, step);
}

}  // namespace

InCycleStats incycle_stats(const std::vector<double>& est, const std::vector<double>& truth,
                           const std::vector<int>& cycle, double step_deg) {
  InCycleStats a;
  const std::size_t n = std::min(est.size(), truth.size());
  if (n < 100) return a;
  double se = 0.0, me = 0.0, mt = 0.0, p2p_sum = 0.0;
  int p2p_n = 0;
  double mn = truth[0], mx = truth[0];
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0 && cycle[i] != cycle[i - 1]) {
      p2p_sum += mx - mn;
      ++p2p_n;
      mn = mx = truth[i];
    }
    mn = std::min(mn, truth[i]);
    mx = std::max(mx, truth[i]);
    se += (est[i] - truth[i]) * (est[i] - truth[i]);
    me += est[i] / static_cast<double>(n);
    mt += truth[i] / static_cast<double>(n);
  }
  const double p2p = p2p_n > 0 ? p2p_sum / p2p_n : mx - mn;
  a.n = static_cast<int>(n);
  a.p2p_nm = p2p;
  a.rms_pct_p2p = 100.0 * std::sqrt(se / static_cast<double>(n)) / p2p;
  a.bias_pct_p2p = 100.0 * (me - mt) / p2p;
  constexpr int kMaxShift = 12;
  std::array<double, 2 * kMaxShift + 1> cc{};
  for (int s = -kMaxShift; s <= kMaxShift; ++s) {
    double acc = 0.0;
    for (std::size_t i = kMaxShift; i + kMaxShift < n; ++i)
      acc += (est[i] - me) * (truth[static_cast<std::size_t>(static_cast<long>(i) - s)] - mt);
    cc[static_cast<std::size_t>(s + kMaxShift)] = acc;
  }
  const auto best = std::max_element(cc.begin(), cc.end()) - cc.begin();
  double frac = 0.0;
  if (best > 0 && best < static_cast<long>(cc.size()) - 1) {
    const double y0 = cc[static_cast<std::size_t>(best - 1)], y1 = cc[static_cast<std::size_t>(best)],
                 y2 = cc[static_cast<std::size_t>(best + 1)];
    const double den = y0 - 2 * y1 + y2;
    if (den != 0.0) frac = 0.5 * (y0 - y2) / den;
  }
  a.lag_deg = (static_cast<double>(best - kMaxShift) + frac) * step_deg;
  return a;
}

std::array<double, kMaxCylinders> per_cylinder_imbalance(const sim::Scenario& sc, const sim::SimOutput& out,
                                                         const std::vector<double>& width_ratio,
                                                         const EvalOptions& opt) {
  AnglePipeline pipe(pipeline_config(sc, opt));
  if (opt.friction) pipe.friction().import_coefficients(*opt.friction);
  std::vector<ToothSample> samples = sim::ideal_tooth_samples(out, sc);
  const int teeth = sc.wheel.teeth();
  for (ToothSample& s : samples) s.width_rad *= width_ratio.at(static_cast<std::size_t>(s.tooth % teeth));
  for (const ToothSample& s : samples)
    pipe.on_tooth(s, sim::signals_at(out, static_cast<double>(s.t_ns) * 1e-9));
  return pipe.cycle_output().cylinders.imbalance_filtered_pct;
}

sim::Scenario once_per_rev_imbalance(int rpm, std::uint64_t seed) {
  sim::Scenario s = steady("imb_rev_" + std::to_string(rpm), rpm, 65.0, seed);
  // +8/−6/−4/+2 %: cylinders 1+4 (+10) against 2+3 (−10), i.e. a large once-per-revolution component.
  s.fuel_factor = {1.08, 0.94, 0.96, 1.02, 1, 1, 1, 1};
  return s;
}

sim::Scenario idle_misfire(std::uint64_t seed) {
  sim::Scenario s;
  s.name = "idle_misfire";
  s.seed = seed;
  s.duration_s = 4.0;
  s.warmup_s = 1.5;
  s.speed_rpm = {{0.0, 800.0}};
  s.load_phases = {{0.0, sim::LoadMode::kTorque}};
  s.load_torque_nm = {{0.0, 0.0}};
  s.throttle_pct = {{0.0, 0.0}};
  s.idle_control = true;
  s.misfires = {{4, 1}, {9, 3}, {13, 4}};
  for (int c = 17; c < 23; ++c) s.misfires.push_back({c, 2});  // cylinder 2 misfiring every cycle
  return s;
}

sim::Scenario idle_after_cut_misfire(std::uint64_t seed) {
  sim::Scenario s = sim::scenario_by_name("fuel_cut");
  s.name = "idle_after_cut_misfire";
  s.seed = seed;
  s.duration_s = 6.0;
  for (int c : {40, 44, 48, 49, 52, 56}) s.misfires.push_back({c, 1 + c % 4});
  return s;
}

std::vector<CylinderCase> cylinder_cases(int random_engines, std::uint64_t seed) {
  std::vector<CylinderCase> cases;
  for (const char* name : {"imbalance", "three_cyl", "wheel_36_1", "misfire", "fuel_cut", "idle"}) {
    cases.push_back({"sim", sim::scenario_by_name(name)});
  }
  std::uint64_t sd = 500;
  for (int rpm : {1000, 2000, 3000, 4000}) cases.push_back({"imb_rev", once_per_rev_imbalance(rpm, sd++)});
  for (int rpm : {1000, 3000}) {
    sim::Scenario s = sim::scenario_by_name("three_cyl");
    s.name = "three_cyl_" + std::to_string(rpm);
    s.speed_rpm = {{0.0, static_cast<double>(rpm)}};
    cases.push_back({"balanced", s});
  }
  cases.push_back({"misfire", idle_misfire(sd++)});
  cases.push_back({"misfire", idle_after_cut_misfire(sd++)});
  for (int rpm : {1000, 2000, 3000, 4000, 6000}) {
    for (double map : {35.0, 65.0, 95.0}) {
      sim::Scenario s = steady("incycle_" + std::to_string(rpm) + "_" + std::to_string(static_cast<int>(map)),
                               rpm, map + (rpm >= 4000 && map < 40.0 ? 10.0 : 0.0), sd++);
      cases.push_back({"incycle", s});
    }
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int e = 0; e < random_engines; ++e) {
    sim::Scenario s = steady("random_" + std::to_string(e), 1000.0 + 2500.0 * u(rng), 45.0 + 45.0 * u(rng),
                             seed * 1000 + static_cast<std::uint64_t>(e));
    const bool three = u(rng) < 0.4;
    s.engine.cylinders = three ? 3 : 4;
    s.engine.firing_order =
        three ? std::array<int, kMaxCylinders>{1, 2, 3} : std::array<int, kMaxCylinders>{1, 3, 4, 2};
    s.engine.bore_m = 0.070 + 0.020 * u(rng);
    s.engine.stroke_m = 0.070 + 0.025 * u(rng);
    s.engine.rod_m = s.engine.stroke_m * (1.55 + 0.3 * u(rng));
    s.engine.j_rot_kgm2 = 0.10 + 0.10 * u(rng);
    s.engine.m_osc_kg = 0.35 + 0.25 * u(rng);
    if (u(rng) < 0.4) {
      s.wheel.positions = 36;
      s.wheel.missing = 1;
    }
    s.sensors.tooth_error_sd_deg = 0.03 + 0.05 * u(rng);
    for (int c = 0; c < s.engine.cylinders; ++c)
      s.fuel_factor[static_cast<std::size_t>(c)] = 0.9 + 0.2 * u(rng);
    cases.push_back({"random", s});
  }
  return cases;
}

bool balanced_seed_row(const CylinderCase& c) {
  const double rpm = c.scenario.speed_rpm.empty() ? 0.0 : c.scenario.speed_rpm.front().value;
  return (c.group == "balanced" || c.group == "incycle") && rpm >= 2000.0;
}

namespace {
/// RMS and worst over `seeds` runs of the max |imbalance error| (pp); the first is the row's own run.
void score_seeds(const CylinderCase& c, const EvalOptions& options, int seeds, CylinderCaseResult& r) {
  constexpr std::uint64_t kSeedStride = 7919;  // far from the neighbouring cases' seeds (500, 501, ...)
  double ss = r.imbalance_max_pp * r.imbalance_max_pp, worst = r.imbalance_max_pp;
  for (int k = 1; k < seeds; ++k) {
    sim::Scenario sc = c.scenario;
    sc.seed += kSeedStride * static_cast<std::uint64_t>(k);
    const double e = evaluate(sc, options).imbalance_max_pp;
    ss += e * e;
    worst = std::max(worst, e);
  }
  r.seeds = seeds;
  r.imbalance_max_rms_pp = std::sqrt(ss / seeds);
  r.imbalance_max_worst_pp = worst;
}
}  // namespace

CylinderCaseResult evaluate_case(const CylinderCase& c, const EvalOptions& options, int seeds) {
  const sim::SimOutput out = sim::simulate(c.scenario);
  const ScenarioResult sr = evaluate(c.scenario, out, options);
  CylinderCaseResult r;
  r.group = c.group;
  r.name = c.scenario.name;
  r.cylinders = c.scenario.engine.cylinders;
  r.mean_rpm = sr.mean_rpm;
  double map = 0.0;
  for (const auto& cy : out.cycles) map += cy.map_pa / 1000.0 / static_cast<double>(out.cycles.size());
  r.map_kpa = map;
  r.imbalance_est = sr.imbalance_est;
  r.imbalance_true = sr.imbalance_true;
  r.imbalance_max_pp = sr.imbalance_max_pp;
  r.misfires_true = sr.misfires_true;
  r.misfires_found = sr.misfires_found;
  r.misfires_false = sr.misfires_false;
  r.detection_active_pct =
      sr.detection_cycles > 0 ? 100.0 * sr.detection_active / static_cast<double>(sr.detection_cycles) : 0.0;
  r.table_low_orders = sr.tooth_low_orders;
  r.tooth_edge_resid_deg = sr.tooth_edge_resid_deg;
  evaluate_incycle(c.scenario, out, options, r);
  if (seeds > 1 && balanced_seed_row(c)) score_seeds(c, options, seeds, r);
  return r;
}

void print_cylinder_table(const std::vector<CylinderCaseResult>& rows, bool header, bool seeds_column) {
  if (header)
    std::printf("%-9s %-20s %2s %5s %4s | %-31s | %-31s | %5s | %s%-16s | %-16s | %s\n", "group", "case", "n",
                "rpm", "kPa", "imbalance est % by cylinder", "error pp by cylinder", "max",
                seeds_column ? "max RMS/worst/N | " : "", "kalman %/deg", "fourier %/deg",
                "misfire found/true/false, detection active %");
  for (const auto& r : rows) {
    char est[64] = "", err[64] = "";
    int pe = 0, pr = 0;
    for (int c = 0; c < r.cylinders; ++c) {
      const auto ci = static_cast<std::size_t>(c);
      pe += std::snprintf(est + pe, sizeof est - static_cast<std::size_t>(pe), "%+7.1f", r.imbalance_est[ci]);
      pr += std::snprintf(err + pr, sizeof err - static_cast<std::size_t>(pr), "%+7.2f",
                          r.imbalance_est[ci] - r.imbalance_true[ci]);
    }
    char seeds[40] = "";
    if (seeds_column && r.seeds > 1)
      std::snprintf(seeds, sizeof seeds, "%5.2f %5.2f %3d | ", r.imbalance_max_rms_pp,
                    r.imbalance_max_worst_pp, r.seeds);
    else if (seeds_column)
      std::snprintf(seeds, sizeof seeds, "%-15s | ", "     -");
    std::printf(
        "%-9s %-20s %2d %5.0f %4.0f | %-31s | %-31s | %5.2f | %s%5.1f %+5.1f %4.1f | %5.1f %+5.1f %4.1f | "
        "%d/%d/%d det %3.0f %%%s\n",
        r.group.c_str(), r.name.c_str(), r.cylinders, r.mean_rpm, r.map_kpa, est, err, r.imbalance_max_pp,
        seeds, r.kalman.rms_pct_p2p, r.kalman.bias_pct_p2p, r.kalman.lag_deg, r.fourier.rms_pct_p2p,
        r.fourier.bias_pct_p2p, r.fourier.lag_deg, r.misfires_found, r.misfires_true, r.misfires_false,
        r.detection_active_pct, r.table_low_orders ? "" : "  (wheel orders held)");
    std::fflush(stdout);
  }
}

}  // namespace torqued::eval
