// torque-sim: crank-angle-resolved engine simulator with ground truth (docs/simulator.md).
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

#include "can_codec.hpp"
#include "cli_exit.hpp"
#include "engine_sim.hpp"
#include "mean_value_engine.hpp"
#include "sim_writer.hpp"

namespace {
using namespace torqued::sim;

/// The command line (see main's options).
struct Args {
  std::string scenario = "demo", out_dir, dbc_path, mode = "crank";
  std::uint64_t seed = 0;
  double duration = 0.0, noise = 0.0;
  bool list = false;
};

void add_options(CLI::App& app, Args& a) {
  app.add_option("-s,--scenario", a.scenario, "scenario name (see --list)");
  app.add_option("-o,--out", a.out_dir, "output directory (created)");
  app.add_option("--seed", a.seed, "override the scenario's seed (0 = keep)");
  app.add_option("--duration", a.duration, "override the duration in seconds (0 = keep)")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_flag("-l,--list", a.list, "list the scenarios and exit");
  app.add_option("--write-dbc", a.dbc_path, "write the CAN database of the simulated messages to this file");
  app.add_option("--mode", a.mode, "crank: crank-angle engine (default); mean-value: Crossley & Cook model")
      ->check(CLI::IsMember({"crank", "mean-value"}));
  app.add_option("--noise", a.noise,
                 "mean-value mode: measurement noise scale (1 = Na's 10 rpm / 2 N m / 0.5 g/s)")
      ->check(CLI::Range(0.0, 100.0));
  app.footer(
      "Exit status: 0 done; 1 unknown scenario, simulation or writing the output failed (message on stderr); "
      "2 command-line error (unknown option, bad value, no --out).");
}

void list_scenarios() {
  for (const auto& n : scenario_names()) {
    const Scenario s = scenario_by_name(n);
    std::printf("%-18s %5.1f s  seed %llu  %d cyl  %d-%d wheel\n", n.c_str(), s.duration_s,
                static_cast<unsigned long long>(s.seed), s.engine.cylinders, s.wheel.positions,
                s.wheel.missing);
  }
}

/// --mode mean-value: Na et al.'s speed-step scenario into mean_value.csv.
void run_mean_value(const Args& a) {
  NaScenarioConfig cfg;
  if (a.seed != 0) cfg.seed = a.seed;
  if (a.duration > 0) cfg.duration_s = a.duration;
  cfg.speed_noise_rpm = 10.0 * a.noise;
  cfg.load_noise_nm = 2.0 * a.noise;
  cfg.maf_noise_g_s = 0.5 * a.noise;
  const auto samples = run_na_scenario(cfg);
  std::string text =
      "t_s,speed_rad_s,load_nm,maf_kg_s,true_speed_rad_s,true_load_nm,true_torque_nm,throttle_deg,p_m_"
      "bar\n";
  char buf[256];
  for (const auto& x : samples) {
    std::snprintf(buf, sizeof buf, "%.6f,%.5f,%.4f,%.7f,%.5f,%.4f,%.4f,%.4f,%.5f\n", x.t_s, x.speed_rad_s,
                  x.load_nm, x.maf_kg_s, x.true_speed_rad_s, x.true_load_nm, x.true_torque_nm, x.throttle_deg,
                  x.p_m_bar);
    text += buf;
  }
  std::filesystem::create_directories(a.out_dir);
  write_text_file(std::filesystem::path(a.out_dir) / "mean_value.csv", text);
  std::fprintf(stderr, "torque-sim: mean-value model, %zu samples -> %s/mean_value.csv\n", samples.size(),
               a.out_dir.c_str());
}

/// The crank-angle engine on the named scenario (progress on a terminal), its files into --out.
void run_crank(const Args& a) {
  Scenario sc = scenario_by_name(a.scenario);
  if (a.seed != 0) sc.seed = a.seed;
  if (a.duration > 0) sc.duration_s = a.duration;
  std::fprintf(stderr, "torque-sim: scenario %s, %.1f s simulated, seed %llu ...\n", sc.name.c_str(),
               sc.duration_s, static_cast<unsigned long long>(sc.seed));
  const auto t0 = std::chrono::steady_clock::now();
  const bool tty = isatty(STDERR_FILENO) != 0;
  const SimOutput out = simulate(sc, [&](double t) {
    if (tty) std::fprintf(stderr, "\r  %.1f / %.1f s simulated", t, sc.duration_s);
  });
  if (tty) std::fprintf(stderr, "\r%40s\r", "");
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_outputs(out, sc, a.out_dir);
  std::fprintf(stderr, "torque-sim: %zu edges, %zu CAN frames, %zu teeth, %zu cycles in %.2f s -> %s\n",
               out.edges.size(), out.can.size(), out.teeth.size(), out.cycles.size(), wall,
               a.out_dir.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "torque-sim: simulate a 4-stroke engine crank-angle by crank-angle (Wiebe combustion, slider-crank "
      "kinematics,\n"
      "variable inertia, friction, dynamometer) and write its sensor signals and ground truth:\n"
      "  edges.csv        crank/cam edges in logic-analyzer CSV (Time [s],crank,cam)\n"
      "  can.log          CAN frames in candump -l format (config/demo.dbc; times = 1700000000 s + t)\n"
      "  truth_tooth.csv  per tooth: time, angle, speed, indicated (total, per cylinder), mass, friction, "
      "load, brake\n"
      "  truth_cycle.csv  per 720 deg cycle: means, per-cylinder indicated torque, misfire and fuel-cut "
      "flags\n"
      "  engine.yaml      engine: and wheel: sections for the torqued config\n"
      "  tooth_errors.csv true machining error of each tooth (tests only)\n"
      "With --mode mean-value it runs the Crossley & Cook mean-value engine of Na et al. 2017 "
      "(docs/time_estimators.md) in\n"
      "their speed-step scenario instead and writes mean_value.csv (measured and true speed, load, air flow, "
      "torque).\n"
      "Example: torque-sim --scenario demo --out data/demo"};
  Args a;
  add_options(app, a);
  TORQUED_CLI_PARSE(app, argc, argv);
  try {
    if (a.list) {
      list_scenarios();
      return 0;
    }
    if (!a.dbc_path.empty()) {
      write_text_file(a.dbc_path, demo_dbc_text());
      std::fprintf(stderr, "wrote %s\n", a.dbc_path.c_str());
      if (a.out_dir.empty()) return 0;
    }
    if (a.out_dir.empty()) {
      std::fprintf(stderr, "error: --out DIR is required (or --list / --write-dbc); see --help\n");
      return 2;
    }
    if (a.mode == "mean-value")
      run_mean_value(a);
    else
      run_crank(a);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "torque-sim: error: %s\n", e.what());
    return 1;
  }
}
