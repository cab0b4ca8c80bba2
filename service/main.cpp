// torqued: engine torque estimation daemon. Thin executable over torqued_daemon / torqued_config.
//   torqued --check-config FILE   validate a configuration, print every error (FILE:LINE:COL: ...), exit 0/1
//   torqued --print-schema [yaml|text]  print every configuration key with default, bounds, unit, description
//   torqued --config FILE         run (pipelines are wired by the daemon part; see docs/daemon.md)
// Exit statuses: the footer of --help (app.footer below).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "cam_check.hpp"
#include "config_loader.hpp"
#include "config_schema.hpp"
#include "daemon_run.hpp"
#include "logging.hpp"
#include "startup_checks.hpp"

#ifndef TORQUED_VERSION
#define TORQUED_VERSION "0.0.0"
#endif

namespace {

int check_config(const std::string& path, bool check_files) {
  const torqued::LoadResult r = torqued::load_config(path, torqued::LoadOptions{check_files});
  for (const auto& w : r.warnings) std::cerr << "warning: " << w << "\n";
  if (!r.ok()) {
    for (const auto& e : r.errors) std::cerr << e << "\n";
    std::cerr << path << ": " << r.errors.size() << " error(s), configuration refused\n";
    return 1;
  }
  const auto& c = *r.config;
  if (const auto refusals = check_files ? torqued::startup_problems(c) : std::vector<std::string>{};
      !refusals.empty()) {  // what the daemon refuses at start beyond the loader (service/startup_checks.hpp)
    for (const auto& e : refusals) std::cerr << e << "\n";
    std::cerr << path << ": " << refusals.size() << " error(s): the daemon would refuse to start\n";
    return 1;
  }
  std::cout << path << ": OK (" << c.engine.cylinders << " cylinders, wheel "
            << (c.wheel.geometry.tooth_count > 0
                    ? std::to_string(c.wheel.geometry.tooth_count) + " listed teeth"
                    : std::to_string(c.wheel.geometry.positions) + "-" +
                          std::to_string(c.wheel.geometry.missing))
            << ", dds domain " << c.dds.domain_id << ")\n";
  if (check_files)
    for (const auto& w : torqued::cam_window_warnings(c)) std::cerr << "warning: " << w << "\n";
  return 0;
}

/// The command line: the three actions (run, check, schema) and the run's overrides.
struct Cli {
  std::string config_path, check_path, schema_format;
  bool no_file_checks = false;
  torqued::RunOptions run;
  std::string mode, record_dir, state_dir;
  double speed = 0.0;
  CLI::Option *run_opt = nullptr, *check_opt = nullptr, *schema_opt = nullptr;
  CLI::Option *mode_opt = nullptr, *speed_opt = nullptr, *record_opt = nullptr, *state_opt = nullptr;
};

void add_options(CLI::App& app, Cli& c) {
  c.run_opt = app.add_option("--config,-c", c.config_path, "run with this YAML configuration")
                  ->check(CLI::ExistingFile);
  c.check_opt =
      app.add_option("--check-config", c.check_path, "validate a configuration file and exit (0 = valid)");
  c.schema_opt =
      app.add_option("--print-schema", c.schema_format, "print every configuration key (yaml|text) and exit")
          ->expected(0, 1)
          ->default_str("yaml");
  app.add_flag("--no-file-checks", c.no_file_checks,
               "with --check-config: do not require the input files to exist");
  c.mode_opt =
      app.add_option("--replay", c.mode,
                     "override replay.mode: fast | paced (fast: with replay.fast_threads 3, or auto on 2+ "
                     "CPUs, inputs read on a second thread, same order)")
          ->check(CLI::IsMember({"fast", "paced"}));
  c.speed_opt = app.add_option("--speed", c.speed, "override replay.speed (paced replay speed factor)")
                    ->check(CLI::PositiveNumber);
  c.record_opt = app.add_option("--record", c.record_dir,
                                "override output.record_dir (CSV recording; in fast replay with three "
                                "threads (replay.fast_threads) written by a thread of its own, in order, "
                                "never dropping)");
  c.state_opt = app.add_option("--state-dir", c.state_dir,
                               "override output.state_dir: learned state loaded at start and saved while "
                               "running and at exit (also in fast replay)");
  app.add_flag("--fresh-state", c.run.fresh_state,
               "do not load the learned state: learn from the prior (the state is still saved)");
  app.add_flag("--no-dds", c.run.no_dds, "do not publish on DDS (record only)");
  app.add_option(
      "--stage-trace", c.run.stage_trace,
      "paced/live: write each CrankState's stamps inside the daemon (edge due, angle thread, "
      "output ring, publisher, dds_write returned; CSV, up to 131072 samples) to this file at exit "
      "(torque-latency's tail stages)");
  app.add_flag("--exit-when-done", c.run.exit_when_done, "paced replay: exit once the recording is consumed");
  app.add_option("--wait-subscribers", c.run.wait_subscribers,
                 "wait (up to 10 s) for this many EngineTorque readers");
  c.check_opt->excludes(c.run_opt);
  c.schema_opt->excludes(c.run_opt)->excludes(c.check_opt);
  app.footer(
      "Exit status:\n"
      "  0  run ended normally (SIGTERM/SIGINT, end of a fast replay, --exit-when-done); --check-config: "
      "valid\n"
      "  1  configuration refused (every error printed as FILE:LINE:COL), an input/DDS/metrics endpoint "
      "could not\n"
      "     be opened, the real-time set-up was refused with realtime.require_rt, or the drain at stop timed "
      "out\n"
      "  2  command-line error: no --config/--check-config/--print-schema, unknown option, bad value, or a "
      "file\n"
      "     that does not exist\n"
      "  3  the CSV recording (output.record_dir / --record) failed; estimation and publishing went on");
}

int print_schema(const std::string& format) {
  if (format.empty() || format == "yaml") {
    std::cout << torqued::schema_example_yaml();
  } else if (format == "text") {
    std::cout << torqued::schema_table_text();
  } else {
    std::cerr << "--print-schema: unknown format '" << format << "', expected yaml or text\n";
    return 2;
  }
  return 0;
}

/// Loads the configuration, applies the command line's overrides and runs the daemon.
int run(Cli& c) {
  const torqued::LoadResult r = torqued::load_config(c.config_path);
  if (!r.ok()) {
    for (const auto& e : r.errors) std::cerr << e << "\n";
    return 1;
  }
  torqued::logging::init(r.config->logging.level);
  for (const auto& w : r.warnings) spdlog::warn("{}", w);
  spdlog::info("torqued {} configuration {} loaded", TORQUED_VERSION, r.config->source_file);
  c.run.config_path = c.config_path;
  if (*c.mode_opt) c.run.mode = c.mode;
  if (*c.speed_opt) c.run.speed = c.speed;
  if (*c.record_opt) c.run.record_dir = c.record_dir;
  if (*c.state_opt) c.run.state_dir = c.state_dir;
  // Config twin of --exit-when-done, for the replays that end: file inputs, not looped (live inputs never
  // end).
  const bool file_inputs = r.config->inputs.edges.backend == torqued::EdgeBackend::kFile;
  if (r.config->replay.exit_when_done && !r.config->replay.loop && file_inputs) c.run.exit_when_done = true;
  return torqued::run_daemon(*r.config, c.run);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "torqued: real-time engine torque estimation from a crank encoder and CAN, published over DDS"};
  app.set_version_flag("--version", std::string("torqued ") + TORQUED_VERSION);
  Cli c;
  add_options(app, c);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);  // prints the message (or the help / version)
    return rc == 0 ? 0 : 2;
  }
  if (*c.schema_opt) return print_schema(c.schema_format);
  if (*c.check_opt) return check_config(c.check_path, !c.no_file_checks);
  if (!*c.run_opt) {
    std::cerr << "torqued: nothing to do: give --config FILE to run, --check-config FILE to validate a "
                 "configuration, or --print-schema\n\n"
              << app.help();
    return 2;
  }
  return run(c);
}
