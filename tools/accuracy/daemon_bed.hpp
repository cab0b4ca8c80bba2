#pragma once
// torque-accuracy --bed unseen-daemon: the unseen-engines bed (tools/sim/unseen_engines.hpp) through the
// daemon's own angle chain. For each bed engine the simulator writes its recordings as a torqued input
// (edges.csv, can.log, demo.dbc, torqued.yaml / torqued_noload.yaml configured from the spec sheet); the
// learning recording is replayed with the load signal (run_fast_replay, as `torqued --replay fast`), its
// learned state is saved as the daemon saves it (checked, state file) and read back; the evaluated recording
// is then replayed from that state with and without the load signal. Every cycle-end record (rolling 720°
// window) is scored against the simulator's truth averaged over the same window (angle-weighted per-tooth
// truth). Not real-time code.
#include <cstdint>
#include <string>
#include <vector>

#include "unseen_engines.hpp"

namespace torqued::eval {

struct DaemonBedStats {
  int n = 0;
  int pass = 0;      ///< within 5 % or 3 N m steady, 8 % or 5 N m transient
  int covered = 0;   ///< |error| <= claimed 1 sigma
  int covered2 = 0;  ///< |error| <= 2 x claimed 1 sigma
  int loose = 0;     ///< within 8 % or 5 N m (the one-point map target)
  int tight = 0;     ///< within the tighter target: 3 % or 2 N m (indicated with the load signal),
                     ///< 10 % or 2 N m (friction); counted for every quantity, meaningful for those two
  double rms_nm = 0.0, max_abs_nm = 0.0, bias_nm = 0.0;
  double rms_true_nm = 0.0;  ///< RMS of the truth over the same cycles (the % figures: rms_nm / rms_true_nm)
};

struct DaemonBedRun {
  int cycles = 0;
  int fused_published = 0;  ///< cycles whose fused brake torque was published (quality not invalid)
  DaemonBedStats brake, indicated, friction, fused;
  /// What limits the fused value (diagnostic): the fused brake with its friction error taken out (fused +
  /// friction error: as if the friction law were exact) and with its indicated error taken out (fused −
  /// indicated error). Exact where the fused value is indicated − friction; else an attribution.
  DaemonBedStats fused_friction_exact, fused_indicated_exact;
};

struct DaemonBedResult {
  std::string engine;
  std::string learned;  ///< what the evaluated runs imported
  DaemonBedRun with_load, without_load;
  double inertia_scale = 1.0;       ///< learned J / spec J carried from the learn run (1: none learned)
  double inertia_true_scale = 1.0;  ///< the hidden true J_rot / spec J_rot of the engine
};

struct DaemonBedOptions {
  std::string out_dir = "bed-daemon";  ///< recordings, state files and configs are left here
  bool short_run = false;              ///< the 4 s evaluated recording
  int skip_cycles = 12;                ///< cycles left out at the start of each evaluated run
  double vehicle_flag_lag_s = 0.0;     ///< --vehicle-bed: the clutch flag late by this (s; 0: the TCU's lead)
};

/// torque-accuracy --vehicle-bed: a vehicle (no load signal) and a hybrid (machine torque and clutch flag on
/// CAN) through the daemon's chain from a fresh state (tools/sim/unseen_engines.hpp bed_vehicle_run,
/// bed_hybrid_run). Each run is one configuration of one recording, scored over a time range.
struct VehicleBedRun {
  std::string label;
  DaemonBedRun r;
};
struct VehicleBedResult {
  std::string engine;
  std::vector<VehicleBedRun> runs;
  int free_coast_cycles = 0;  ///< vehicle/noflag: cycles taken as a free coast-down (no flag)
  int free_coast_wrong = 0;   ///< of them, with the simulator's clutch closed at either end of the window
  bool noflag_saved_friction = false;  ///< the state vehicle/noflag left holds a friction law
};
/// Labels: (b) hybrid/open (standstill charging, clutch flag mapped), hybrid/drive (driving after it),
/// hybrid/drive static-false and static-true (can.e_machine.sole_load without the flag: the behaviour before
/// it existed), vehicle/noflag (no clutch signal), vehicle/neutral (VEH_1.ClutchOpen mapped as
/// can.signals.neutral); (a) is vehicle/noflag. (c) one-point/map: the map recording (bed_eval_run) without
/// its load signal, from the state a learning run with the load signal at one operating point left
/// (bed_one_point_learning_run); never/map: the same from a fresh state (nothing learned anywhere).
bool evaluate_vehicle_bed_engine(const sim::BedEngine& e, const DaemonBedOptions& opt, VehicleBedResult& r,
                                 std::string& error);

/// torque-accuracy --bed-priors: the map recording (bed_eval_run) without its load signal from a fresh state,
/// per cycle whose fused value rests on the priors alone: the generic friction law's and the fuel model's
/// relative errors (estimate − truth) / estimate, and each error in units of its claimed 1σ (z), also the
/// fused brake's. The 68th percentile of z over a set of engines is the factor their claimed 1σ is off by.
struct PriorCalibration {
  std::string engine;
  std::vector<double> friction_rel, friction_z, fuel_rel, fuel_z, fused_z;
};
bool evaluate_prior_calibration_engine(const sim::BedEngine& e, const DaemonBedOptions& opt,
                                       PriorCalibration& r, std::string& error);
/// --bed-priors (prior_bed.cpp): the calibration engines (with `all` also the bed's tuning and report
/// engines) per engine and pooled by role, with a bootstrap over engines; 0, or 1 if an engine failed.
int run_bed_priors(bool all, const DaemonBedOptions& opt);

/// One engine; false with `error` set when a recording could not be written or replayed.
bool evaluate_bed_engine_daemon(const sim::BedEngine& e, const DaemonBedOptions& opt, DaemonBedResult& r,
                                std::string& error);

}  // namespace torqued::eval
