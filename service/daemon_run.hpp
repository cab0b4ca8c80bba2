#pragma once
// `torqued --config FILE`: builds sources, stages, DDS publisher and recorder from the Config and runs
//   fast replay  (replay.mode fast): single-threaded, deterministic, then exits;
//   paced/live   (replay.mode paced, or live backends): the Runtime threads, supervised here:
//                sd_notify READY/STATUS/WATCHDOG/STOPPING, SIGTERM/SIGINT drain + flush (bounded),
//                SIGHUP reload of the safe parts, periodic atomic save of the learned state.
#include <optional>
#include <string>

namespace torqued {

struct Config;

struct RunOptions {
  std::string config_path;                ///< for SIGHUP reloads
  std::optional<std::string> mode;        ///< override replay.mode: "fast" | "paced"
  std::optional<double> speed;            ///< override replay.speed
  std::optional<std::string> record_dir;  ///< override output.record_dir
  std::optional<std::string> state_dir;   ///< override output.state_dir
  bool fresh_state = false;  ///< do not load the learned state (learn from the prior); still saved
  bool no_dds = false;       ///< do not create a DDS participant (recording only)
  std::string
      stage_trace;  ///< paced/live: write each CrankState's stamps in the daemon here at exit ("" off)
  bool exit_when_done = false;  ///< paced replay: exit once the input is consumed
  int wait_subscribers = 0;     ///< wait until this many readers matched EngineTorque (or time-out)
  double wait_subscribers_timeout_s = 10.0;
  double drain_timeout_s = 2.0;      ///< SIGTERM: bound on draining rings + flushing
  double state_save_period_s = 5.0;  ///< learned state saved this often (and at exit)
};

/// Returns the process exit code (0 = clean shutdown).
int run_daemon(const Config& cfg, const RunOptions& opt);

}  // namespace torqued
