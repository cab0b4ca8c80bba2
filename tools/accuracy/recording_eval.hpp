#pragma once
// torque-accuracy --recording: a recording (edge CSV + candump, as a config names them) through the daemon's
// own angle chain (run_fast_replay: the same code as `torqued --replay fast`), so a figure printed here is a
// figure of the daemon. Writes the recording's topics to out_dir exactly as `torqued --replay fast --record
// out_dir
// --no-dds` does (a test asserts byte identity), plus chain_cycle.csv: per cycle the chain's internal values
// that EngineTorque does not carry (cycle-energy brake, crank-only indicated, RLS extended load, ESO).
#include <string>
#include <vector>

namespace torqued::eval {

struct RecordingOptions {
  std::string config_path;
  std::string out_dir;
  std::string truth_cycle;  ///< truth_cycle.csv ("" = no evaluation)
  std::string state_dir;    ///< learned state loaded before and saved after ("" = none)
  double skip_s = 0.0;      ///< evaluation starts this long after the first edge (convergence)
};

/// Returns the process exit code (0 ok, 1 run/evaluation error, 2 bad configuration); messages on stderr.
int run_recording(const RecordingOptions& opt);

}  // namespace torqued::eval
