#pragma once
// Learned state (friction coefficients, per-tooth angle corrections) persisted across restarts.
//
// Format (text, version 2, exact round trip with %.17g):
//   torqued-state 2
//   identity engine_id=1 cylinders=4 bore_m=0.0825 stroke_m=0.086 wheel=60-2 teeth=58
//   friction <c1> <c2> <c3> <c4>                    (optional)
//   friction_idle <correction N m> <idle speed rpm>  (optional: FrictionLearner's local idle correction)
//   friction_residual <N m> <count>                  (optional: 68th percentile of |motoring residual|, the
//                                                    claimed 1 sigma of a window in fuel cut-off)
//   tooth_corrections <n> <rad_0> ... <rad_n-1>      (optional)
//   fuel_model <eta> <p_exh V_d/4pi N m> <P00> <P01> <P10> <P11> <resid var N m^2> <references>
//              [<68th percentile of |residual| N m> <its count>]  (optional; the last two added later: 0 0
//              or absent = not measured yet)
//              [physics <c0> <c1> <p_off Pa> <k_bp Pa> <P 4x4, 16 values> <references per speed x MAP cell,
//              16>] (optional, the physics model of fuel_torque.hpp; eta and p_exh are then its values at the
//              reference point. A line without it, as older files have, loads: the two-parameter state is
//              converted, the parameters it did not have start at their priors)
//   crank_error_var <N m^2>                          (optional: measured variance of the crank-only chain)
//   inertia <k> <information 1/k^2> <J_spec kg m^2>  (optional: J = k x J_spec, InertiaLearner; J_spec is the
//                                                    engine.j_rot_kgm2 it was learned against)
//   burn_phase <offset deg> <used cycles>           (optional: BurnPhaseLearner, the in-cycle gas model's
//   burn
//                                                    centroid offset)
//   saved_at_t_ns <edge-clock time>
//   checksum crc32 <8 hex digits of CRC-32 (IEEE) over every byte before this line>
// fuel_model, crank_error_var, inertia and friction_residual were added to version 2 (learning without a load
// signal); version 2 files without them still load. Version 1 files (no identity, no checksum) are still read
// and checked against the bounds; the next save rewrites them as version 2.
//
// The record is LearnedState (learned_state.hpp). Each line between the identity and the checksum is one row
// of the line table in state_store.cpp (keyword, kinds of its numbers, count field, optional trailing values,
// physical bounds check): serialize_state, parse_state and check_state all walk that table, so a new learned
// quantity is its field, its row and its place in the chain (see learned_state.hpp).
//
// Writes are atomic: <file>.tmp is written and fsync()ed, the current file (always a checked one) is
// hard-linked to <file>.bak, then <file>.tmp is renamed over <file> and the directory fsync()ed. A crash or
// kill -9 at any moment leaves the old or the new complete file, never a torn one.
//
// Loading (restore_learned_state) checks, in this order: format and checksum, identity (engine and wheel of
// this configuration), physical bounds of every value (StateContext). A file failing any check is set aside
// (renamed <file>.rejected-<UTC time>) and reported as a warning; the backup is tried next; without a good
// one learning restarts from the configured prior. Saves run on StateSaver's own thread, so a slow disk never
// holds up the supervisor (systemd watchdog, status, SIGTERM). Not real-time.
#include <array>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "learned_state.hpp"
#include "params.hpp"

namespace torqued {

struct Config;

/// What a state file must match and the physical bounds its values must respect (from the configuration).
struct StateContext {
  std::string identity;           ///< engine and wheel this daemon runs (identity line)
  int teeth = 0;                  ///< expected number of tooth corrections (real teeth of the wheel)
  double max_tooth_corr_rad = 0;  ///< |correction| < min(half a tooth pitch, tooth_learn.max_correction_deg)
  FrictionParams friction;        ///< law (sign) and speed range the coefficients are evaluated over
  double max_friction_nm = 0;  ///< |T_fric| bound over n in [0, friction.max_rpm], t_oil in [-40, 200] degC
  /// Upper bound of the gross indicated efficiency: the air-standard Otto cycle at the configured compression
  /// ratio, 1 - r^(1-gamma) with gamma = 1.4 (Heywood 1988 eq. 5.31); no real cycle converts more.
  double max_eta = 1.0;
  double max_torque_sd_nm = 0;   ///< bound of a learned 1 sigma (N m): the torque of kMaxFrictionMepPa
  double min_inertia_scale = 0;  ///< bounds of the learned inertia scale (estimators.energies.inertia)
  double max_inertia_scale = 0;
  double min_burn_offset_deg =
      0;  ///< bounds of the learned burn-phase offset (estimators.kalman.burn_phase_*)
  double max_burn_offset_deg = 0;
};

/// Friction mean effective pressure no engine reaches (Pa): 50 bar. Motored friction is 1-3 bar fmep at rated
/// speed (Heywood, Internal Combustion Engine Fundamentals, 2nd ed. 2018, ch. 13) and the highest production
/// brake mean effective pressures are about 30 bar, so a friction law above 50 bar is a corrupt file (a
/// friction of 1e12, or e-06 typed as e+06), never a learned value. T = fmep V_d / (4 pi) for a four-stroke.
inline constexpr double kMaxFrictionMepPa = 50e5;

/// Identity, tooth count and bounds of `cfg`. The friction bound is the larger of kMaxFrictionMepPa's torque
/// and twice the configured prior's largest |T_fric| (a configured prior is always accepted).
[[nodiscard]] StateContext state_context_from(const Config& cfg);

/// Text of `s` in format version 2 with `identity` and its checksum.
[[nodiscard]] std::string serialize_state(const LearnedState& s, const std::string& identity);
/// Parses `text` (format and checksum only); nullopt with `error` naming `name`:line on failure.
std::optional<LearnedState> parse_state(const std::string& text, const std::string& name, std::string* error);
/// Identity and physical bounds: false with `error` naming `name` and the offending value.
bool check_state(const LearnedState& s, const StateContext& ctx, const std::string& name, std::string* error);

/// Writes atomically (see above), keeping the current file as <path>.bak; false with `error` set on any
/// failure (the old file stays intact).
bool save_state_atomic(const std::string& path, const LearnedState& s, const std::string& identity,
                       std::string* error);
/// Same with the identity of `s` (tests, tools).
bool save_state_atomic(const std::string& path, const LearnedState& s, std::string* error);
/// Reads and parses (format and checksum, no identity/bounds: see restore_learned_state).
std::optional<LearnedState> load_state(const std::string& path, std::string* error);

struct RestoreResult {
  std::optional<LearnedState> state;  ///< checked state to import (nullopt: start from the prior)
  std::vector<std::string> warnings;  ///< to log at warning level (rejected files, where they were moved)
  std::vector<std::string> infos;     ///< to log at info level
  bool may_save = true;  ///< false when a rejected file could not be set aside (saving would destroy it)
};
/// Loads `path` (else <path>.bak), checks it against `ctx`, sets rejected files aside (see above).
[[nodiscard]] RestoreResult restore_learned_state(const std::string& path, const StateContext& ctx);

/// Saves learned state on its own thread: submit() never waits for the disk.
class StateSaver {
 public:
  using Writer = std::function<bool(const LearnedState&, std::string* error)>;
  /// Writes with save_state_atomic(path, ., ctx.identity) (after check_state: nothing out of bounds is
  /// saved).
  StateSaver(std::string path, StateContext ctx);
  /// Writes with `writer` (tests: a slow or failing disk).
  explicit StateSaver(Writer writer);
  ~StateSaver();  ///< finish(5 s)
  StateSaver(const StateSaver&) = delete;
  StateSaver& operator=(const StateSaver&) = delete;

  /// Queues `s` for writing (replaces a queued one not yet started). Returns at once.
  void submit(LearnedState s);
  /// Waits until the queue is written, at most `timeout_s`; false on time-out (the thread is then left to
  /// finish on its own: the old file stays intact whatever happens).
  bool finish(double timeout_s);
  /// Errors of failed saves since the last call (for the supervisor to log).
  [[nodiscard]] std::vector<std::string> take_errors();
  [[nodiscard]] std::uint64_t saves() const;
  [[nodiscard]] std::uint64_t failures() const;

 private:
  struct Shared;
  static void run(const std::shared_ptr<Shared>& sh);
  std::shared_ptr<Shared> sh_;
  std::thread thread_;
};

}  // namespace torqued
