// torque-accuracy: runs simulator scenarios through the angle pipeline and prints the accuracy table vs truth
// (cycle-mean accuracy targets). Friction is learned first on the "fuel_cut" coast-down from a zero prior
// (the pipeline is not told the simulator's friction law), then imported into every scenario, as the daemon
// would persist it.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli_exit.hpp"
#include "cylinder_eval.hpp"
#include "daemon_bed.hpp"
#include "incycle_bed.hpp"
#include "misfire_bed.hpp"
#include "pipeline_eval.hpp"
#include "recording_eval.hpp"

using torqued::eval::ErrorStats;

namespace {
std::string cell(const ErrorStats& s) {
  if (s.n == 0) return "        -        ";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%5.1f %4.1f%% %3d%%", s.max_abs_nm, s.max_rel_pct, 100 * s.pass / s.n);
  return buf;
}
std::string rm(const ErrorStats& s) {
  if (s.n == 0) return "     -      -";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%6.1f %6.1f", s.rms_nm, s.max_abs_nm);
  return buf;
}
std::string pass_cov(const ErrorStats& s) {
  if (s.n == 0) return "   -    -";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%3d%% %3d%%", 100 * s.pass / s.n,
                s.with_sd > 0 ? 100 * s.covered / s.with_sd : 0);
  return buf;
}

/// The accuracy table of the unseen-engines bed.
int run_bed(bool all, bool short_run, const torqued::eval::EvalOptions& base) {
  std::printf(
      "unseen-engines bed (%s runs): estimators configured from the spec sheet only; friction starts from "
      "the\n"
      "generic Barnes-Moss prior, is learned on a learning recording (idle + overrun), and the evaluated\n"
      "recording starts from that state. Cells: RMS and max |error| (N m) over every cycle after %d;\n"
      "pass = %% cycles within 5 %% or 3 N m steady, 8 %% or 5 N m transient; cov = %% cycles with |error| "
      "<= claimed 1 sigma.\n",
      short_run ? "short" : "full", base.skip_cycles);
  std::printf("%-11s %4s | %-25s | %-13s | %-13s | %-25s | %-13s | %-13s | %s\n", "engine", "cyc",
              "WITH LOAD brake rms max", "indicated", "friction", "WITHOUT brake rms max", "indicated",
              "fused", "brake pass/cov  ind pass/cov");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    const auto b = torqued::eval::evaluate_bed_engine(e, base, short_run);
    const auto& w = b.with_load;
    const auto& n = b.without_load;
    std::printf("%-11s %4d | %-13s %-11s | %-13s | %-13s | %-13s %-11s | %-13s | %-13s | %s  %s\n",
                b.engine.c_str(), w.cycles, rm(w.brake).c_str(), pass_cov(w.brake).c_str(),
                rm(w.indicated).c_str(), rm(w.friction).c_str(), rm(n.brake).c_str(),
                pass_cov(n.brake).c_str(), rm(n.indicated).c_str(), rm(n.fused).c_str(),
                pass_cov(n.brake).c_str(), pass_cov(n.indicated).c_str());
    std::fflush(stdout);
  }
  return 0;
}

/// Hybrid input: the bed with an electric machine of `ratio` as the load (no dynamometer signal).
int run_bed_e_machine(bool all, bool short_run, const torqued::eval::EvalOptions& base, double ratio) {
  std::printf(
      "unseen-engines bed with an electric machine (ratio %.3g) as the load, no dynamometer signal; learned "
      "with the\n"
      "machine as the known sole load. Cells: RMS and max |error| (N m), pass/cov as the bed table.\n",
      ratio);
  std::printf("%-11s %4s | %-25s | %-13s | %-25s | %-13s\n", "engine", "cyc",
              "MACHINE brake rms max pass/cov", "indicated", "CONTROL (unbound) brake", "friction");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    const auto b = torqued::eval::evaluate_bed_e_machine(e, base, short_run, ratio);
    const auto& m = b.with_machine;
    const auto& c = b.control;
    std::printf("%-11s %4d | %-13s %-11s | %-13s | %-13s %-11s | %-13s\n", b.engine.c_str(), m.cycles,
                rm(m.brake).c_str(), pass_cov(m.brake).c_str(), rm(m.indicated).c_str(), rm(c.brake).c_str(),
                pass_cov(c.brake).c_str(), rm(m.friction).c_str());
    std::fflush(stdout);
  }
  return 0;
}

/// Hybrid input: friction learned from motoring by the machine vs the generic prior.
int run_bed_motoring(bool all, bool short_run, const torqued::eval::EvalOptions& base, double ratio) {
  std::printf(
      "friction learned from motoring by the electric machine (ratio %.3g; fuel cut-off, 1000-4000 rpm "
      "plateaus),\n"
      "scored on the evaluated recording. Cells: RMS and max |error| (N m), %% cycles within 10 %% or 2 N "
      "m.\n",
      ratio);
  std::printf("%-11s | %-13s %-5s | %-13s %-5s | %s\n", "engine", "PRIOR rms max", "pass", "LEARNED rms max",
              "pass", "motoring observations");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    const auto b = torqued::eval::evaluate_bed_motoring(e, base, short_run, ratio);
    const auto pct = [](const ErrorStats& s) { return s.n > 0 ? 100 * s.pass / s.n : 0; };
    std::printf("%-11s | %-13s %4d%% | %-13s %4d%% | %llu\n", b.engine.c_str(), rm(b.prior.friction).c_str(),
                pct(b.prior.friction), rm(b.learned.friction).c_str(), pct(b.learned.friction),
                static_cast<unsigned long long>(b.motoring.friction_observations));
    std::fflush(stdout);
  }
  return 0;
}

/// The fuel model without a load signal: taught at one operating point, and never taught.
std::string fuel_cells(const torqued::eval::BedFuelRun& f) {
  char buf[96];
  const int pub = std::max(f.published, 1);
  std::snprintf(buf, sizeof buf, "%4d%% %5.1f %5.1f%% %5.1f %4d%% %4d%%",
                f.cycles > 0 ? 100 * f.published / f.cycles : 0, f.rms_nm, f.rms_pct, f.bias_nm,
                100 * f.pass / pub, 100 * f.covered / pub);
  return buf;
}
void write_fuel_csv(const std::string& path, const torqued::eval::BedFuelRun& f) {
  std::ofstream o(path);
  o << "t_s,transient,speed_rpm,brake_true_nm,fused_nm,fused_sd_nm,quality,indicated_true_nm,indicated_nm,"
       "friction_true_nm,friction_nm\n";
  for (const auto& w : f.rows)
    o << w.t_s << ',' << w.transient << ',' << w.speed_rpm << ',' << w.brake_true << ',' << w.fused << ','
      << w.fused_sd << ',' << torqued::to_string(w.quality) << ',' << w.indicated_true << ',' << w.indicated
      << ',' << w.friction_true << ',' << w.friction << '\n';
}
int run_bed_fuel(bool all, bool short_run, const torqued::eval::EvalOptions& base,
                 const std::string& csv_dir) {
  std::printf(
      "fuel model without a load signal (fused brake torque of the evaluated recording, no load signal):\n"
      "  ONE POINT: learned on a recording with the load signal at one operating point (2500 rpm, 60 kPa) "
      "plus\n"
      "             an overrun and idle; NEVER: nothing learned anywhere (fuel-model and friction priors).\n"
      "Cells: published share, RMS error (N m), RMS / RMS true (%%), bias (N m), within 8 %% or 5 N m, "
      "|error| <= claimed 1 sigma;\n"
      "refs / cells: fuel-model references and learned speed x MAP cells (4x4 mask); load: fused RMS WITH "
      "the load\n"
      "signal from the one-point state (N m).\n");
  std::printf("%-11s | %-36s | %-9s | %-36s | %s\n", "engine", "ONE POINT pub rms rms% bias pass cov",
              "refs/cell", "NEVER pub rms rms% bias pass cov", "load");
  // Pooled over the report engines (and over the tuning engines when listed): cycles of all engines together.
  struct Pool {
    torqued::eval::BedFuelRun one, never;
    double se1 = 0, st1 = 0, se0 = 0, st0 = 0;
  } pool[2];
  const auto pool_add = [](torqued::eval::BedFuelRun& p, double& se, double& st,
                           const torqued::eval::BedFuelRun& f) {
    p.cycles += f.cycles;
    p.published += f.published;
    p.pass += f.pass;
    p.covered += f.covered;
    se += f.rms_nm * f.rms_nm * f.published;
    st += f.rms_pct > 0.0 ? f.rms_nm * f.rms_nm * f.published / (f.rms_pct * f.rms_pct / 1e4) : 0.0;
    p.bias_nm += f.bias_nm * f.published;
  };
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    const auto b = torqued::eval::evaluate_bed_fuel(e, base, short_run);
    Pool& pl = pool[e.report ? 1 : 0];
    pool_add(pl.one, pl.se1, pl.st1, b.one_point);
    pool_add(pl.never, pl.se0, pl.st0, b.never);
    if (!csv_dir.empty()) {
      write_fuel_csv(csv_dir + "/" + b.engine + "_one_point.csv", b.one_point);
      write_fuel_csv(csv_dir + "/" + b.engine + "_never.csv", b.never);
    }
    std::printf("%-11s | %s | %4u/%04x | %s | %4.2f\n", b.engine.c_str(), fuel_cells(b.one_point).c_str(),
                b.one_point.references, b.one_point.cells, fuel_cells(b.never).c_str(), b.with_load_rms_nm);
    std::fflush(stdout);
  }
  for (int k = 0; k < 2; ++k) {
    Pool& p = pool[k];
    if (p.one.cycles == 0) continue;
    for (auto* x : {&p.one, &p.never}) {
      const double se = x == &p.one ? p.se1 : p.se0, st = x == &p.one ? p.st1 : p.st0;
      x->rms_nm = x->published > 0 ? std::sqrt(se / x->published) : 0.0;
      x->rms_pct = st > 0.0 ? 100.0 * std::sqrt(se / st) : 0.0;
      x->bias_nm = x->published > 0 ? x->bias_nm / x->published : 0.0;
    }
    std::printf("%-11s | %s | %9s | %s |\n", k == 1 ? "REPORT all" : "TUNING all", fuel_cells(p.one).c_str(),
                "", fuel_cells(p.never).c_str());
  }
  return 0;
}

/// In-cycle torque from a fresh start without any fuel cut-off (incycle_bed.hpp).
/// The burn-phasing learner's end state under an in-cycle bed row (only when it ran).
void print_burn_phase(const torqued::eval::BurnPhaseSummary& b) {
  if (!b.on) return;
  static constexpr const char* kState[] = {"not used", "learning", "converged"};
  const auto& st = b.stats;
  std::printf(
      "  burn phase: offset %+.2f deg, %s, %llu cycles used (mean model lag %+.2f deg; not used: cut %llu, "
      "map %llu, spark %llu, model %llu, incomplete %llu, small %llu)\n",
      b.offset_deg, kState[static_cast<int>(st.state)], static_cast<unsigned long long>(st.cycles_used),
      st.mean_phase_deg, static_cast<unsigned long long>(st.cycles_cutoff),
      static_cast<unsigned long long>(st.cycles_no_map), static_cast<unsigned long long>(st.cycles_no_spark),
      static_cast<unsigned long long>(st.cycles_no_model),
      static_cast<unsigned long long>(st.cycles_incomplete),
      static_cast<unsigned long long>(st.cycles_small_ripple));
}

int run_bed_incycle(bool all, bool short_run, const torqued::eval::EvalOptions& base, const std::string& only,
                    int digits) {
  std::printf(
      "in-cycle indicated torque from a FRESH start, no fuel cut-off (%s firing recording: dyno plateaus\n"
      "1500-3200 rpm, 40-88 kPa; tooth learner empty at start, learning on the recording, its table applied "
      "at "
      "each\n"
      "cycle end). Scored over the steady parts of the last two plateaus (1500, 2200 rpm): RMS %% of the "
      "mean "
      "per-cycle\n"
      "p2p, bias %%, lag deg (+: behind). ready: when the table was first applied; edge: residual of the "
      "final "
      "table vs\n"
      "the true wheel (deg RMS); orders: per-rev order 1.. of the fit (h held, o overrun, O overrun-speeds, "
      "s "
      "speeds,\n"
      "f firing).\n",
      short_run ? "20 s" : "60 s");
  std::printf("%-11s | %-18s | %-18s | %6s | %7s | %6s | %-6s %s\n", "engine", "kalman % bias lag",
              "fourier % bias lag", "ready", "edge", "cycles", "orders", "quality");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if ((!all && !e.report && only.empty()) || (!only.empty() && e.name != only)) continue;
    const auto r = torqued::eval::evaluate_incycle_fresh(e, base, short_run);
    std::printf("%-11s | %5.*f %+5.1f %+5.*f | %5.1f %+5.1f %+5.1f | %5.1fs | %7.4f | %6llu | %-6s %s\n",
                r.engine.c_str(), digits, r.kalman.rms_pct_p2p, r.kalman.bias_pct_p2p, digits,
                r.kalman.lag_deg, r.fourier.rms_pct_p2p, r.fourier.bias_pct_p2p, r.fourier.lag_deg,
                r.ready_at_s, r.tooth_edge_resid_deg, static_cast<unsigned long long>(r.cycles_used),
                r.orders.c_str(), torqued::to_string(r.quality));
    const torqued::eval::InCycleRegime& ea = r.early;
    if (r.ready_at_s >= 0.0)  // a learned table (not --true-tooth-errors / --no-tooth-table)
      std::printf(
          "  early 8 s after ready: kalman %.*f %% %+.*f deg cover %.0f%%, fourier %.*f %% %+.*f deg\n",
          digits, ea.kalman.rms_pct_p2p, digits, ea.kalman.lag_deg, ea.kalman_cover_pct, digits,
          ea.fourier.rms_pct_p2p, digits, ea.fourier.lag_deg);
    print_burn_phase(r.burn);
    std::fflush(stdout);
  }
  return 0;
}

/// In-cycle torque through transients and a fuel cut-off entry/exit after a fresh start (incycle_bed.hpp).
int run_bed_incycle_regimes(bool all, const torqued::eval::EvalOptions& base, const std::string& only,
                            int digits, const std::string& ramp_dump) {
  std::printf(
      "\nin-cycle indicated torque after the 20 s fresh start (tooth table learned on the recording), then "
      "bed_eval_run:\nTRANSIENTS (20.5-27 s: speed ramps 1500-3500 rpm, throttle steps 35-90 kPa) and a FUEL "
      "CUT-OFF at 3500 rpm\n(closed throttle, dyno dragging towards 2500 rpm, 1 s) scored from 0.2 s before "
      "its "
      "entry to 2.5 s after its exit.\nRMS %% of p2p, lag deg, cover: Kalman teeth within its claimed 1 "
      "sigma "
      "(%%); slow: RMS of the per-cycle mean\nerror, worst1s: worst RMS over 1 s (%% of p2p).\n"
      "RAMP: a fresh start in the demo's shape (idle, ramps to 3500 rpm at 35-90 kPa, a cut-off), 0-15 s.\n");
  std::printf("%-11s | %-9s | %-20s | %-11s | %-13s\n", "engine", "regime", "kalman % lag cover",
              "slow worst1s", "fourier % lag");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if ((!all && !e.report && only.empty()) || (!only.empty() && e.name != only)) continue;
    const auto r = torqued::eval::evaluate_incycle_regimes(e, base);
    for (int k = 0; k < 2; ++k) {
      const torqued::eval::InCycleRegime& g = k == 0 ? r.transient : r.cutoff;
      std::printf("%-11s | %-9s | %5.*f %+5.*f %5.0f%% | %5.1f %5.1f | %5.1f %+5.1f\n", r.engine.c_str(),
                  k == 0 ? "transient" : "cut-off", digits, g.kalman.rms_pct_p2p, digits, g.kalman.lag_deg,
                  g.kalman_cover_pct, g.kalman_slow_pct, g.kalman_worst_s_pct, g.fourier.rms_pct_p2p,
                  g.fourier.lag_deg);
    }
    print_burn_phase(r.burn);
    const auto m = torqued::eval::evaluate_incycle_ramp(e, base, ramp_dump);
    const auto& g = m.ramp;
    std::printf("%-11s | %-9s | %5.*f %+5.*f %5.0f%% | %5.1f %5.1f | %5.1f %+5.1f | ready %.1fs\n",
                m.engine.c_str(), "ramp", digits, g.kalman.rms_pct_p2p, digits, g.kalman.lag_deg,
                g.kalman_cover_pct, g.kalman_slow_pct, g.kalman_worst_s_pct, g.fourier.rms_pct_p2p,
                g.fourier.lag_deg, m.ready_at_s);
    print_burn_phase(m.burn);
    std::fflush(stdout);
  }
  return 0;
}

/// Misfire found/true/false and per-cylinder imbalance from idle to 6000 rpm (misfire_bed.hpp).
int run_bed_misfire(bool all, const torqued::eval::EvalOptions& base) {
  std::printf(
      "misfire and imbalance on the unseen engines: idle 800 rpm (idle controller, declutched), mid "
      "2500 rpm\n60 kPa, high 6000 rpm 80 kPa, each with 2 single misfires, a pair in one cycle and one "
      "cylinder in 2 cycles\nrunning; weak: one cylinder at 85 %% fuel, 2200 rpm 60 kPa. found/true/false "
      "per cylinder and cycle; active:\ncycles where detection was possible; imbalance: filtered - true "
      "(pp, RMS over the cylinders / max).\n");
  std::printf("%-11s | %-6s | %5s | %-15s | %6s | %-13s\n", "engine", "regime", "rpm", "found/true/false",
              "active", "imbalance pp");
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    for (const std::string& regime : torqued::eval::misfire_bed_regimes()) {
      const auto r = torqued::eval::evaluate_misfire_bed(e, regime, base);
      std::printf("%-11s | %-6s | %5.0f | %4d %4d %5d  | %5.0f%% | %5.2f %5.2f\n", r.engine.c_str(),
                  r.regime.c_str(), r.mean_rpm, r.found, r.truth, r.false_alarms, r.detection_active_pct,
                  r.imbalance_rms_pp, r.imbalance_max_pp);
      std::fflush(stdout);
    }
  }
  return 0;
}

std::string ds(const torqued::eval::DaemonBedStats& s) {
  if (s.n == 0) return "     -      -";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%6.1f %6.1f", s.rms_nm, s.max_abs_nm);
  return buf;
}
std::string dpc(const torqued::eval::DaemonBedStats& s) {
  if (s.n == 0) return "   -    -";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%3d%% %3d%%", 100 * s.pass / s.n, 100 * s.covered / s.n);
  return buf;
}

/// Pooled statistics of one run label over the report engines (vehicle bed summary).
struct Pool {
  int cycles = 0, published = 0;
  torqued::eval::DaemonBedStats brake, fused, fused_friction_exact, fused_indicated_exact;
};
void pool_add(torqued::eval::DaemonBedStats& p, const torqued::eval::DaemonBedStats& s) {
  const auto sq = [](double v, int n) { return v * v * n; };
  const int n = p.n + s.n;
  if (n == 0) return;
  p.rms_nm = std::sqrt((sq(p.rms_nm, p.n) + sq(s.rms_nm, s.n)) / n);
  p.rms_true_nm = std::sqrt((sq(p.rms_true_nm, p.n) + sq(s.rms_true_nm, s.n)) / n);
  p.max_abs_nm = std::max(p.max_abs_nm, s.max_abs_nm);
  p.pass += s.pass;
  p.loose += s.loose;
  p.covered += s.covered;
  p.n = n;
}
double rel(const torqued::eval::DaemonBedStats& s) {
  return s.rms_true_nm > 0.0 ? 100.0 * s.rms_nm / s.rms_true_nm : 0.0;
}

void print_vehicle_bed_header(const torqued::eval::DaemonBedOptions& opt) {
  std::printf(
      "Vehicle bed (%s recordings in %s, daemon chain, no load signal in any evaluated run). Per run:\n"
      "cycles; brake, indicated, friction: RMS / max |error| (N m) and cov = %% of cycles with |error| <=\n"
      "claimed 1 sigma; pass = %% of brake within 5 %% or 3 N m steady, 8 %% or 5 N m transient; fused = %% "
      "of cycles whose fused brake was published, then its\n"
      "RMS / max |error| and RMS / RMS true over those (brake scores the chain's brake on every cycle).\n"
      "(a) vehicle/noflag: idle in neutral, driving, overrun in gear, neutral coast-down, no clutch signal,\n"
      "    fresh state (vehicle/neutral: the same with the clutch flag mapped as can.signals.neutral);\n"
      "    ... 2nd: a second drive, the same recording from the state the first drive left (no flag: what\n"
      "    the free coast-down recognised from the crank and the fuel, and the idle after it, taught).\n"
      "(b) hybrid/open: standstill charging at 3 points, clutch open (em_sole_load flag mapped), fresh "
      "state;\n"
      "    hybrid/drive: driving after it (clutch closed, boost, generation, overrun in gear); "
      "static-false/\n"
      "    true: the same recording with can.e_machine.sole_load fixed, no flag (controls).\n"
      "(c) one-point/map: the map (1000-3000 rpm, 35-92 kPa) without load signal, from the state of a "
      "learning\n"
      "    run with the load signal at 2500 rpm plus an overrun and idle; never/map: the map, fresh state.\n",
      opt.short_run ? "short" : "full", opt.out_dir.c_str());
  std::printf("%-10s %-26s %4s | %-13s %-9s | %-13s %4s | %-13s %4s | %5s %-13s %5s %4s\n", "engine", "run",
              "cyc", "brake", "pass/cov", "indicated", "cov", "friction", "cov", "fused", "RMS    max",
              "rms%", "cov");
}

/// The summary over the report engines and the targets, each with its verdict.
void print_vehicle_bed_summary(const std::map<std::string, Pool>& pools) {
  std::printf(
      "\nREPORT engines pooled: run, cycles, fused published, fused RMS (N m, %% of RMS true), brake "
      "pass, fused 1 sigma coverage\n");
  for (const auto& [label, p] : pools) {
    std::printf("  %-26s %5d  pub %3d%%  RMS %5.1f N m %5.1f %%  pass %3d%%  cov %3d%%\n", label.c_str(),
                p.cycles, p.cycles ? 100 * p.published / p.cycles : 0, p.fused.rms_nm, rel(p.fused),
                p.brake.n ? 100 * p.brake.pass / p.brake.n : 0,
                p.fused.n ? 100 * p.fused.covered / p.fused.n : 0);
  }
  const auto get = [&](const char* k) {
    const auto it = pools.find(k);
    return it == pools.end() ? Pool{} : it->second;
  };
  const auto verdict = [](bool ok) { return ok ? "met" : "NOT met"; };
  const Pool a = get("vehicle/noflag"), b = get("hybrid/drive"), c = get("one-point/map"),
             n = get("never/map"), a2 = get("vehicle/noflag 2nd");
  const auto pc = [](int k, int m) { return m > 0 ? 100.0 * k / m : 0.0; };
  std::printf("Targets:\n");
  std::printf(
      "  (b) hybrid driving brake within 5 %%/3 N m steady, 8 %%/5 N m transient: %.0f %% of cycles: %s\n",
      pc(b.brake.pass, b.brake.n), verdict(pc(b.brake.pass, b.brake.n) >= 95.0));
  std::printf("  (c) one point, the whole map (fused) within 8 %% or 5 N m: %.0f %% of cycles: %s\n",
              pc(c.fused.loose, c.fused.n), verdict(pc(c.fused.loose, c.fused.n) >= 95.0));
  for (const auto& [name, p] :
       {std::pair{"(a) never taught, vehicle", a}, std::pair{"    never taught, map", n},
        std::pair{"    no flag, 2nd drive", a2}}) {
    const double pub = pc(p.published, p.cycles), cov = pc(p.fused.covered, p.fused.n);
    std::printf("  %s: published %.0f %% (>= 95), RMS %.1f %% (<= 12), 1 sigma covers %.0f %% (60-76): %s\n",
                name, pub, rel(p.fused), cov,
                verdict(pub >= 95.0 && rel(p.fused) <= 12.0 && cov >= 60.0 && cov <= 76.0));
  }
  std::printf(
      "What limits them (diagnostic: the fused RMS with one error taken out: friction exact / indicated "
      "exact):\n");
  for (const auto& [name, p] :
       {std::pair{"vehicle/noflag", a}, std::pair{"never/map", n}, std::pair{"vehicle/noflag 2nd", a2}})
    std::printf("  %-26s RMS %.1f %%: friction exact %.1f %%, indicated exact %.1f %%\n", name, rel(p.fused),
                rel(p.fused_friction_exact), rel(p.fused_indicated_exact));
}

/// --vehicle-bed: (a) a vehicle, (b) a hybrid, (c) one operating point taught, on the bed's engines through
/// the daemon's chain (daemon_bed.hpp); the pooled summary over the report engines with the targets.
int run_vehicle_bed(bool all, const torqued::eval::DaemonBedOptions& opt) {
  print_vehicle_bed_header(opt);
  int rc = 0;
  const auto pct = [](int k, int m) { return m > 0 ? 100 * k / m : 0; };
  std::map<std::string, Pool> pools;
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    torqued::eval::VehicleBedResult b;
    std::string err;
    if (!torqued::eval::evaluate_vehicle_bed_engine(e, opt, b, err)) {
      std::fprintf(stderr, "error: %s\n", err.c_str());
      rc = 1;
      continue;
    }
    for (const auto& run : b.runs) {
      const auto& w = run.r;
      std::printf("%-10s %-26s %4d | %-13s %-9s | %-13s %3d%% | %-13s %3d%% | %4d%% %s %4.1f%% %3d%%\n",
                  b.engine.c_str(), run.label.c_str(), w.cycles, ds(w.brake).c_str(), dpc(w.brake).c_str(),
                  ds(w.indicated).c_str(), pct(w.indicated.covered, w.indicated.n), ds(w.friction).c_str(),
                  pct(w.friction.covered, w.friction.n), pct(w.fused_published, w.cycles),
                  ds(w.fused).c_str(), rel(w.fused), pct(w.fused.covered, w.fused.n));
      if (!e.report) continue;
      Pool& p = pools[run.label];
      p.cycles += w.cycles;
      p.published += w.fused_published;
      pool_add(p.brake, w.brake);
      pool_add(p.fused, w.fused);
      pool_add(p.fused_friction_exact, w.fused_friction_exact);
      pool_add(p.fused_indicated_exact, w.fused_indicated_exact);
    }
    std::printf(
        "%-10s vehicle/noflag: %d cycles taken as a free coast-down (no flag), %d of them with the "
        "clutch closed\n",
        b.engine.c_str(), b.free_coast_cycles, b.free_coast_wrong);
    std::fflush(stdout);
  }
  print_vehicle_bed_summary(pools);
  return rc;
}

/// Without a load signal, through the daemon's chain: the unseen-engines bed as recordings replayed by
/// run_fast_replay.
int run_bed_daemon(bool all, const torqued::eval::DaemonBedOptions& opt) {
  std::printf(
      "unseen-engines bed THROUGH THE DAEMON'S CHAIN (%s runs): each engine's recordings written as "
      "edges.csv +\n"
      "can.log + demo.dbc + torqued config (spec sheet) under %s/; learn recording replayed with the load "
      "signal\n"
      "(run_fast_replay), its learned state saved/restored as the daemon does, evaluated recording replayed "
      "from\n"
      "that state with and without the load signal. Cells: RMS and max |error| (N m) over every cycle-end "
      "record\n"
      "after %d; pass = %% within 5 %% or 3 N m steady, 8 %% or 5 N m transient; cov = %% with |error| <= "
      "claimed "
      "1 sigma; 2cov: no-load brake within 2 sigma; tgt = %% of cycles within the tighter targets "
      "(indicated\n"
      "with the load signal 3 %% or 2 N m, friction 10 %% or 2 N m); J k/true: learned and true inertia / "
      "spec "
      "sheet.\n",
      opt.short_run ? "short" : "full", opt.out_dir.c_str(), opt.skip_cycles);
  std::printf(
      "%-10s %4s | %-13s %-9s | %-13s %4s | %-13s %4s | %-13s %-9s | %-13s %-9s | %-13s | %-13s %4s | %4s | "
      "%s\n",
      "engine", "cyc", "LOAD brake", "pass/cov", "indicated", "tgt", "friction", "tgt", "NO LOAD brake",
      "pass/cov", "indicated", "pass/cov", "fused", "friction", "tgt", "2cov", "J k/true");
  int rc = 0;
  for (const auto& e : torqued::sim::unseen_engines()) {
    if (!all && !e.report) continue;
    torqued::eval::DaemonBedResult b;
    std::string err;
    if (!torqued::eval::evaluate_bed_engine_daemon(e, opt, b, err)) {
      std::fprintf(stderr, "error: %s\n", err.c_str());
      rc = 1;
      continue;
    }
    const auto& w = b.with_load;
    const auto& n = b.without_load;
    const auto pct = [](int k, int m) { return m > 0 ? 100 * k / m : 0; };
    std::printf(
        "%-10s %4d | %-13s %-9s | %-13s %3d%% | %-13s %3d%% | %-13s %-9s | %-13s %-9s | %-13s | %-13s %3d%% "
        "| %3d%% | "
        "%.3f/%.3f\n",
        b.engine.c_str(), w.cycles, ds(w.brake).c_str(), dpc(w.brake).c_str(), ds(w.indicated).c_str(),
        pct(w.indicated.tight, w.indicated.n), ds(w.friction).c_str(), pct(w.friction.tight, w.friction.n),
        ds(n.brake).c_str(), dpc(n.brake).c_str(), ds(n.indicated).c_str(), dpc(n.indicated).c_str(),
        ds(n.fused).c_str(), ds(n.friction).c_str(), pct(n.friction.tight, n.friction.n),
        pct(n.brake.covered2, n.brake.n), b.inertia_scale, b.inertia_true_scale);
    std::fflush(stdout);
  }
  return rc;
}

/// The command line: main's options with their defaults (the help text shows them).
struct Args {
  std::vector<std::string> names;
  bool raw_teeth = false, true_teeth = false, paper_prior = false;
  int skip = 12;
  double can_lost = -1.0;
  std::string csv_dir, bed;
  bool bed_all = false, bed_short = false;
  bool cylinders = false;
  int random_engines = 4;
  std::uint64_t random_seed = 15;
  torqued::eval::RecordingOptions rec;
  std::string bed_out = "bed-daemon";
  bool vehicle_bed = false, bed_priors = false;
  double vehicle_flag_lag = 0.0;
  double bed_machine = 0.0;
  bool bed_motoring = false, bed_fuel = false, bed_incycle = false, bed_misfire = false;
  bool regimes_only = false;
  std::string bed_engine, incycle_dump, incycle_regimes_dump, ramp_dump;
  int incycle_digits = 1;
  int cylinder_seeds = 1;
  torqued::ToothLearnParams learn;
  bool no_firing_law = false;
  bool spark_column = false, no_spark_column = false;
  bool burn_phase_learn = false, no_burn_phase_learn = false;
  torqued::KalmanParams kalman;
  torqued::FourierParams fourier;
  double burn_duration_deg = -1.0, evo_deg = -1.0, centroid_deg = -1000.0, burn_delay = -1.0;
  bool fixed_centroid = false;
  double kappa_c = -1.0, kappa_e = -1.0, wiebe_a = -1.0, wiebe_m = -1.0;
  bool no_gas_model = false;
};

// The options, in the order the help lists them: scenarios, recording, beds, cylinders, tooth learner and
// in-cycle observers.
void add_scenario_options(CLI::App& app, Args& a) {
  app.add_option("-s,--scenario", a.names, "scenario(s); default: all built-in scenarios");
  app.add_flag("--raw-teeth", a.raw_teeth, "do not correct tooth widths (nominal wheel)");
  app.add_flag(
      "--true-tooth-errors", a.true_teeth,
      "correct tooth widths with the simulator's TRUE machining errors instead of the learned table");
  app.add_flag("--paper-friction", a.paper_prior,
               "start friction learning from the paper's coefficients instead of 0");
  app.add_option("--skip", a.skip, "cycles skipped at the start of each scenario (convergence)");
  app.add_option("--can-lost-after", a.can_lost,
                 "drop all CAN signals from this time on (s): crank-only fallback");
  app.add_option("--csv", a.csv_dir, "write per-cycle comparison CSVs into this directory");
}

void add_recording_options(CLI::App& app, Args& a) {
  app.add_option(
         "--recording", a.rec.config_path,
         "instead of the scenarios: replay the recording a torqued config names through the daemon's own "
         "angle chain; writes its topics (as torqued --replay fast --record) and chain_cycle.csv to --out")
      ->check(CLI::ExistingFile);
  app.add_option("--out", a.rec.out_dir, "--recording: output directory")->default_str("accuracy-out");
  app.add_option("--truth", a.rec.truth_cycle, "--recording: truth_cycle.csv to evaluate against")
      ->check(CLI::ExistingFile);
  app.add_option("--state-dir", a.rec.state_dir,
                 "--recording: learned state loaded at start and saved at the end");
  app.add_option("--skip-s", a.rec.skip_s,
                 "--recording: seconds after the first edge left out of the evaluation");
}

void add_bed_options(CLI::App& app, Args& a) {
  app.add_option(
         "--bed", a.bed,
         "run a test bed instead of the scenarios: 'unseen' (report engines, ideal teeth into a "
         "copy of "
         "the pipeline) or 'unseen-daemon' (the same engines as recordings through the daemon's chain)")
      ->check(CLI::IsMember({"unseen", "unseen-daemon"}));
  app.add_option("--bed-out", a.bed_out,
                 "--bed unseen-daemon: directory for the recordings, configs and state files");
  app.add_flag(
      "--vehicle-bed", a.vehicle_bed,
      "run the vehicle bed: a vehicle (no load signal; clutch flag unmapped / as neutral) and a hybrid "
      "(machine torque and clutch flag on CAN) on the report engines through the daemon's chain "
      "(--bed-out, --bed-short, --bed-all apply)");
  app.add_flag("--bed-priors", a.bed_priors,
               "measure the generic priors' error (friction correlation, fuel model) on the calibration "
               "engines: the map without a load signal from a fresh state; prints the 68th percentile of "
               "|error| / claimed 1 sigma, the factor the priors' 1 sigma is off by (--bed-all: also the "
               "bed's tuning and report engines, pooled apart; --bed-out, --bed-short apply)");
  app.add_option(
         "--vehicle-flag-lag", a.vehicle_flag_lag,
         "with --vehicle-bed: the clutch flag on CAN is late by this (s) instead of leading the clutch "
         "(robustness)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_flag("--bed-all", a.bed_all, "with --bed: also the tuning engines");
  app.add_flag("--bed-short", a.bed_short, "with --bed: the short evaluated recordings (the ctest subset)");
  app.add_option(
         "--bed-e-machine", a.bed_machine,
         "with --bed unseen: an electric machine of this ratio (machine/crank speed) is the load; brake "
         "with the machine torque bound (sole load) and a control run with it unbound")
      ->check(CLI::PositiveNumber);
  app.add_flag(
      "--bed-misfire", a.bed_misfire,
      "with --bed unseen: misfire found/true/false at idle, 2500 and 6000 rpm (single and paired) "
      "and the per-cylinder imbalance of an engine with one weak cylinder (with --bed-incycle: after the "
      "in-cycle tables, the in-cycle targets' whole table from one command)");
  app.add_flag(
      "--bed-incycle", a.bed_incycle,
      "with --bed unseen: in-cycle Kalman/Fourier torque from a fresh start without any fuel cut-off "
      "(tooth learner empty at start; --true-tooth-errors / --raw-teeth for the floor / no table), then "
      "through transients and a fuel cut-off entry/exit");
  app.add_flag("--bed-incycle-regimes", a.regimes_only,
               "with --bed unseen: only the transient, fuel cut-off and ramp rows of --bed-incycle");
  app.add_option("--bed-engine", a.bed_engine,
                 "with --bed-incycle / --bed-incycle-regimes: only this bed engine (tuning or report)");
  app.add_option(
         "--bed-incycle-digits", a.incycle_digits,
         "with --bed-incycle: decimals of the Kalman's RMS % and lag (2 for sweeps whose steps are small)")
      ->check(CLI::Range(1, 3));
  app.add_option("--bed-incycle-dump", a.incycle_dump,
                 "with --bed-incycle and --bed-engine: write that engine's fresh start per tooth (truth, gas "
                 "model ripple, Kalman estimate, scored window) to this CSV file (tools/accuracy/"
                 "incycle_orders.py decomposes it)");
  app.add_option(
      "--bed-incycle-regimes-dump", a.incycle_regimes_dump,
      "with --bed-incycle or --bed-incycle-regimes and --bed-engine: the same per-tooth CSV for that "
      "engine's transient and cut-off run (scored 1 transient, 2 cut-off; docs/eval.md)");
  app.add_option("--bed-incycle-ramp-dump", a.ramp_dump,
                 "with --bed-incycle(-regimes) and --bed-engine: the same CSV for the ramp from idle");
  app.add_flag(
      "--bed-fuel", a.bed_fuel,
      "with --bed unseen: the fuel model without a load signal, taught at one operating point and never "
      "taught (published share, RMS, 1 sigma coverage)");
  app.add_flag(
      "--bed-motoring", a.bed_motoring,
      "with --bed unseen: friction learned from motoring by the machine (ratio --bed-e-machine, default 1) "
      "vs the generic prior");
}

void add_cylinder_options(CLI::App& app, Args& a) {
  app.add_flag("--cylinders", a.cylinders,
               "per-cylinder table instead: imbalance error per cylinder and speed, in-cycle RMS and lag, "
               "misfires, on the simulator's scenarios and randomised engines");
  app.add_option("--random-engines", a.random_engines, "--cylinders: number of randomised engines");
  app.add_option("--random-seed", a.random_seed, "--cylinders: seed of the randomised engines");
  app.add_option(
         "--cylinder-seeds", a.cylinder_seeds,
         "--cylinders: balanced rows at >= 2000 rpm also run on this many simulator seeds in all (RMS and "
         "worst of the max imbalance error; 1: the single run only)")
      ->check(CLI::Range(1, 100));
}

void add_observer_options(CLI::App& app, Args& a) {
  app.add_option("--fit-harmonics", a.learn.fit_harmonics, "tooth learner: harmonics of the per-cycle fit");
  app.add_option("--incycle-sd", a.learn.incycle_sd, "in-cycle 1σ with the table's (tooth_learn.incycle_sd)");
  app.add_flag(
      "--no-firing-load-law", a.no_firing_law,
      "tooth learner: orders are not learned from the firing cycles' load law (the learner before it)");
  app.add_flag(
      "--spark-column", a.spark_column,
      "tooth learner: the firing orders' load law with the spark advance column (tooth_learn.spark_column)");
  app.add_flag("--no-spark-column", a.no_spark_column,
               "tooth learner: the firing orders' load law without the spark advance column");
  app.add_flag("--burn-phase-learn", a.burn_phase_learn,
               "in-cycle beds: learn the gas model's burn-centroid offset (kalman.burn_phase_learn)");
  app.add_flag("--no-burn-phase-learn", a.no_burn_phase_learn,
               "in-cycle beds: the gas model's burn centroid without the learned offset");
  app.add_option("--speed-weight-exp", a.learn.speed_weight_exp,
                 "tooth learner: residuals weighted by speed^p");
  app.add_option("--kalman-lag", a.kalman.smoother_lag, "Kalman fixed-lag smoother (teeth)");
  app.add_option("--kalman-torque-sd", a.kalman.torque_sd_nm,
                 "Kalman process noise without the gas model: 1 sigma of the net torque (N m)");
  app.add_option("--kalman-delta", a.kalman.delta, "Kalman coloured-noise pole (1/rad)");
  app.add_option("--kalman-model-delta", a.kalman.model_delta,
                 "Kalman coloured-noise pole with the gas model valid (1/rad)");
  app.add_option("--kalman-model-torque-sd", a.kalman.model_torque_sd_nm,
                 "Kalman process noise with the gas model valid: 1 sigma of what the model misses (N m)");
  app.add_option("--kalman-edge-noise", a.kalman.edge_noise_deg, "Kalman R: edge-angle error (deg)");
  app.add_option("--kalman-jitter", a.kalman.jitter_s, "Kalman R: timestamp jitter (s)");
  app.add_option("--burn-duration", a.burn_duration_deg,
                 "with --bed-incycle: the in-cycle gas torque model's burn duration (deg; default "
                 "energies.burn_duration_deg)")
      ->check(CLI::Range(0.0, 180.0));
  app.add_option(
         "--burn-centroid", a.centroid_deg,
         "with --bed-incycle: the burn centroid without a spark advance or with --fixed-burn-centroid "
         "(deg after firing TDC; default energies.burn_centroid_atdc_deg)")
      ->check(CLI::Range(-90.0, 180.0));
  app.add_flag("--fixed-burn-centroid", a.fixed_centroid,
               "with --bed-incycle: the in-cycle gas model's burn centroid fixed (--burn-centroid), not from "
               "the spark advance (energies.incycle_spark_phasing false: as before)");
  app.add_option("--burn-delay", a.burn_delay,
                 "with --bed-incycle: spark to burn centroid (deg; default energies.burn_delay_deg)")
      ->check(CLI::Range(0.0, 180.0));
  app.add_option(
         "--evo", a.evo_deg,
         "with --bed-incycle: the pressure model's exhaust valve opening (deg after firing TDC; default "
         "energies.evo_atdc_deg)")
      ->check(CLI::Range(90.0, 180.0));
  app.add_option("--kappa-compression", a.kappa_c,
                 "with --bed-incycle: the in-cycle gas model's compression exponent (default "
                 "energies.incycle_compression_kappa)")
      ->check(CLI::Range(0.0, 2.0));
  app.add_option("--kappa-expansion", a.kappa_e,
                 "with --bed-incycle: the in-cycle gas model's expansion exponent (default "
                 "energies.incycle_expansion_kappa)")
      ->check(CLI::Range(0.0, 2.0));
  app.add_option(
         "--wiebe-a", a.wiebe_a,
         "with --bed-incycle: the in-cycle gas model's burn shape, Wiebe a (0: raised cosine; default "
         "energies.burn_wiebe_a)")
      ->check(CLI::Range(0.0, 20.0));
  app.add_option("--wiebe-m", a.wiebe_m, "with --bed-incycle: Wiebe m (default energies.burn_wiebe_m)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_flag("--no-gas-model", a.no_gas_model,
               "Kalman and Fourier observer without the cylinder-pressure model's gas torque ripple as known "
               "input (as in the papers)");
  app.add_option("--fourier-lref", a.fourier.l_ref, "Fourier observer L_ref");
  app.add_option("--fourier-lke", a.fourier.l_ke, "Fourier observer L_ke");
  app.add_option("--fourier-model-lref", a.fourier.model_l_ref,
                 "Fourier observer L_ref with the gas model valid");
  app.add_option("--fourier-harmonics", a.fourier.harmonics, "Fourier observer n_h");
  app.add_option("--fourier-gain-ref-rpm", a.fourier.gain_ref_rpm,
                 "Fourier observer gain reference speed (rpm)");
}

// --bed unseen: the bed the flags choose (fuel, misfire, in-cycle, motoring, e-machine, else the brake bed).
int run_unseen_bed(Args& a) {
  torqued::eval::EvalOptions bo;
  bo.skip_cycles = a.skip;
  if (a.bed_fuel) return run_bed_fuel(a.bed_all, a.bed_short, bo, a.csv_dir);
  const bool incycle = a.bed_incycle || a.regimes_only;
  if (a.bed_misfire && !incycle) return run_bed_misfire(a.bed_all, bo);
  if (incycle) {
    const torqued::eval::EvalOptions misfire_bo =
        bo;  // the misfire bed's own defaults, not the in-cycle flags
    bo.tooth_table = a.raw_teeth    ? torqued::eval::ToothTable::kNone
                     : a.true_teeth ? torqued::eval::ToothTable::kTrue
                                    : torqued::eval::ToothTable::kLearned;
    bo.tooth_learn = a.learn;
    a.kalman.gas_model = !a.no_gas_model;
    a.fourier.gas_model = !a.no_gas_model;
    bo.base.kalman = a.kalman;
    bo.base.fourier = a.fourier;
    if (a.burn_duration_deg >= 0.0) bo.base.energies.burn_duration_deg = a.burn_duration_deg;
    if (a.evo_deg >= 0.0) bo.base.energies.evo_atdc_deg = a.evo_deg;
    if (a.centroid_deg > -1000.0) bo.base.energies.burn_centroid_atdc_deg = a.centroid_deg;
    if (a.burn_delay >= 0.0) bo.base.energies.burn_delay_deg = a.burn_delay;
    if (a.fixed_centroid) bo.base.energies.incycle_spark_phasing = false;
    if (a.kappa_c >= 0.0) bo.base.energies.incycle_compression_kappa = a.kappa_c;
    if (a.kappa_e >= 0.0) bo.base.energies.incycle_expansion_kappa = a.kappa_e;
    if (a.wiebe_a >= 0.0) bo.base.energies.burn_wiebe_a = a.wiebe_a;
    if (a.wiebe_m >= 0.0) bo.base.energies.burn_wiebe_m = a.wiebe_m;
    torqued::eval::EvalOptions fresh = bo;
    fresh.incycle_dump = a.incycle_dump;
    bo.incycle_regimes_dump = a.incycle_regimes_dump;
    int rc =
        a.regimes_only ? 0 : run_bed_incycle(a.bed_all, a.bed_short, fresh, a.bed_engine, a.incycle_digits);
    if (rc == 0) rc = run_bed_incycle_regimes(a.bed_all, bo, a.bed_engine, a.incycle_digits, a.ramp_dump);
    // with --bed-misfire too: the misfire and weak-cylinder table after the in-cycle ones, one command for
    // all
    return rc != 0 || !a.bed_misfire ? rc : run_bed_misfire(a.bed_all, misfire_bo);
  }
  if (a.bed_motoring)
    return run_bed_motoring(a.bed_all, a.bed_short, bo, a.bed_machine > 0.0 ? a.bed_machine : 1.0);
  if (a.bed_machine > 0.0) return run_bed_e_machine(a.bed_all, a.bed_short, bo, a.bed_machine);
  return run_bed(a.bed_all, a.bed_short, bo);
}

// --vehicle-bed, --bed unseen-daemon or --bed unseen.
int run_beds(Args& a) {
  if (a.bed_priors) {
    torqued::eval::DaemonBedOptions o;
    o.out_dir = a.bed_out == "bed-daemon" ? "bed-priors" : a.bed_out;
    o.short_run = a.bed_short;
    o.skip_cycles = a.skip;
    return torqued::eval::run_bed_priors(a.bed_all, o);
  }
  if (a.vehicle_bed) {
    torqued::eval::DaemonBedOptions o;
    o.out_dir = a.bed_out == "bed-daemon" ? "bed-vehicle" : a.bed_out;
    o.vehicle_flag_lag_s = a.vehicle_flag_lag;
    o.short_run = a.bed_short;
    o.skip_cycles = a.skip;
    return run_vehicle_bed(a.bed_all, o);
  }
  if (a.bed == "unseen-daemon") {
    torqued::eval::DaemonBedOptions o;
    o.out_dir = a.bed_out;
    o.short_run = a.bed_short;
    o.skip_cycles = a.skip;
    return run_bed_daemon(a.bed_all, o);
  }
  return run_unseen_bed(a);
}

void write_cycles_csv(const std::string& path, const torqued::eval::ScenarioResult& r) {
  std::ofstream f(path);
  f << "t_s,transient,speed_rpm,brake_nm,brake_true_nm,indicated_nm,indicated_true_nm,friction_nm,"
       "friction_true_nm,"
       "load_rls_nm,load_star_true_nm,indicated_crank_nm,indicated_eso_nm,fused_nm,quality\n";
  for (const auto& w : r.rows) {
    f << w.t_s << ',' << w.transient << ',' << w.speed_rpm << ',' << w.brake << ',' << w.brake_true << ','
      << w.indicated << ',' << w.indicated_true << ',' << w.friction << ',' << w.friction_true << ','
      << w.load_rls << ',' << w.load_star_true << ',' << w.indicated_crank << ',' << w.indicated_eso << ','
      << w.fused << ',' << torqued::to_string(w.quality) << '\n';
  }
}

// The simulator's scenarios (or --cylinders' table): friction learned first, then one row per scenario.
int run_scenarios(Args& a) {
  const std::vector<std::string> known = torqued::sim::scenario_names();
  if (a.names.empty() && !a.cylinders) a.names = known;
  for (const auto& name : a.names) {
    if (a.cylinders || std::find(known.begin(), known.end(), name) != known.end()) continue;
    std::string list;
    for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
    std::fprintf(stderr, "torque-accuracy: --scenario: unknown scenario '%s'; known: %s\n", name.c_str(),
                 list.c_str());
    return 2;
  }

  torqued::eval::EvalOptions opt;
  using torqued::eval::ToothTable;
  opt.tooth_table = a.raw_teeth ? ToothTable::kNone : a.true_teeth ? ToothTable::kTrue : ToothTable::kLearned;
  opt.skip_cycles = a.skip;
  opt.tooth_learn = a.learn;
  a.kalman.gas_model = !a.no_gas_model;
  a.fourier.gas_model = !a.no_gas_model;
  opt.base.kalman = a.kalman;
  opt.base.fourier = a.fourier;
  opt.can_lost_after_s = a.can_lost;
  if (a.paper_prior) opt.friction_prior = torqued::kEnergiesPaperFrictionC;
  const auto fric = torqued::eval::learn_friction(opt);
  std::printf("friction learned on fuel_cut (prior %s): C1=%.3f C2=%.4g C3=%.4g C4=%.4g\n",
              a.paper_prior ? "paper" : "zero", fric[0], fric[1], fric[2], fric[3]);
  opt.friction = fric;
  std::printf("tooth table: %s\n",
              a.raw_teeth    ? "none (nominal widths)"
              : a.true_teeth ? "simulator's true machining errors"
                             : "learned by ToothErrorLearner on a warm-up recording of the same wheel "
                               "(1000-4000 rpm plateaus + fuel cut-off, 5 s)");
  if (a.cylinders) {
    std::vector<torqued::eval::CylinderCaseResult> rows;
    for (const auto& c : torqued::eval::cylinder_cases(a.random_engines, a.random_seed)) {
      if (!a.names.empty() && std::find(a.names.begin(), a.names.end(), c.scenario.name) == a.names.end())
        continue;
      rows.push_back(torqued::eval::evaluate_case(c, opt, a.cylinder_seeds));
      torqued::eval::print_cylinder_table({rows.back()}, rows.size() == 1, a.cylinder_seeds > 1);
    }
    return 0;
  }
  std::printf("%-16s %5s %4s | %-17s | %-17s | %-17s | %-17s | %-17s | %-17s | %6s | %-14s | %s\n",
              "scenario", "rpm", "cyc", "brake (CAN)", "indicated", "fused", "brake crank-only", "RLS load*",
              "ESO indicated", "imb pp", "tooth ° w/e", "misfire found/true/false");
  for (const auto& name : a.names) {
    const auto sc = torqued::sim::scenario_by_name(name);
    const auto r = torqued::eval::evaluate(sc, opt);
    std::printf("%-16s %5.0f %4d | %s | %s | %s | %s | %s | %s | %6.2f | %.4f/%.3f%s | %d/%d/%d\n",
                name.c_str(), r.mean_rpm, r.cycles, cell(r.brake).c_str(), cell(r.indicated).c_str(),
                cell(r.fused).c_str(), cell(r.brake_crank).c_str(), cell(r.load_rls).c_str(),
                cell(r.indicated_eso).c_str(), r.imbalance_max_pp, r.tooth_resid_deg, r.tooth_edge_resid_deg,
                opt.tooth_table == ToothTable::kLearned && !r.tooth_low_orders ? "*" : " ", r.misfires_found,
                r.misfires_true, r.misfires_false);
    std::fflush(stdout);
    if (!a.csv_dir.empty()) write_cycles_csv(a.csv_dir + "/" + name + "_cycles.csv", r);
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  Args a;  // before app, which binds its members
  CLI::App app{
      "Accuracy of the angle pipeline (brake, indicated, fused, crank-only, RLS load, ESO, per-cylinder,\n"
      "misfire) on the simulator's scenarios. Cells: max |error| N m, max |error| % of truth, % of cycles\n"
      "within tolerance (3 % or 2 N m steady, 5 % or 3 N m in transients)."};
  add_scenario_options(app, a);
  add_recording_options(app, a);
  add_bed_options(app, a);
  add_cylinder_options(app, a);
  add_observer_options(app, a);
  app.footer(
      "Exit status: 0 done (tables printed); 1 a recording could not be read or the output not written; 2 "
      "command-line error (unknown option or scenario, bad value, file that does not exist) or --config "
      "refused / its "
      "inputs cannot be opened.");
  TORQUED_CLI_PARSE(app, argc, argv);
  a.learn.firing_load_law = !a.no_firing_law;
  if (a.spark_column) a.learn.spark_column = true;
  if (a.no_spark_column) a.learn.spark_column = false;
  if (a.burn_phase_learn) a.kalman.burn_phase.learn = true;
  if (a.no_burn_phase_learn) a.kalman.burn_phase.learn = false;
  if (!a.rec.config_path.empty()) {
    if (a.rec.out_dir.empty()) a.rec.out_dir = "accuracy-out";
    return torqued::eval::run_recording(a.rec);
  }
  if (a.vehicle_bed || a.bed_priors || !a.bed.empty()) return run_beds(a);
  return run_scenarios(a);
}
