#pragma once
// The supervisor of the paced replay and live modes (the caller's thread, over the Runtime's threads):
// learned state restored before start and saved off-thread while running, DaemonStatus every status period,
// sd_notify READY/STATUS/WATCHDOG/STOPPING, signals (SIGTERM/SIGINT drain and stop, SIGHUP reloads the safe
// parts), the recording's health, and the bounded shutdown. Fast replay does not need it (fast_replay.cpp,
// daemon_run.cpp).
#include <string>

#include "daemon_run.hpp"
#include "decoder_events.hpp"
#include "replay_inputs.hpp"
#include "rt_setup.hpp"
#include "sample_recorder.hpp"
#include "sample_sink.hpp"
#include "state_store.hpp"

namespace torqued {

struct Config;
struct ThreadConfig;

/// The real-time settings of one thread as configured (realtime.<thread>).
[[nodiscard]] ThreadRt thread_rt(const ThreadConfig& t, const char* name);

/// <state_dir>/learned_state.txt of the run ("" when no state directory is configured).
[[nodiscard]] std::string state_path(const Config& cfg, const RunOptions& opt);
/// The checked learned state of the previous run, as every mode loads it: identity, checksum and physical
/// bounds checked, rejected files set aside (state_store.hpp); nothing with --fresh-state. Logs what
/// happened.
[[nodiscard]] RestoreResult restore_for_run(const std::string& spath, const StateContext& ctx,
                                            const RunOptions& opt);

/// One decoder sync-state transition at debug level, with its edge time.
void log_transition(const DecoderEvent& e);

/// Runs the paced replay or live mode until a signal (or --exit-when-done); returns the exit code
/// (0 clean, 1 start-up failure or drain time-out, 3 recording failed).
int run_supervised(Config& cfg, const RunOptions& opt, RunInputs& in, dds::SampleRecorder* recorder,
                   SampleSink& out);

}  // namespace torqued
