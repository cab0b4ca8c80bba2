#pragma once
// Per-cylinder truth: imbalance error per cylinder and speed, in-cycle indicated torque RMS and
// lag per speed and load, misfires found/true/false, on the simulator's scenarios and on engines with
// randomised geometry, tooth errors and imbalance patterns that nothing in torqued was tuned on. Not
// real-time code.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "engine_sim.hpp"
#include "pipeline_eval.hpp"

namespace torqued::eval {

struct CylinderCase {
  std::string group;  ///< "imbalance", "balanced", "misfire", "incycle", "random"
  sim::Scenario scenario;
};

/// In-cycle accuracy of one per-tooth estimate against the simulator's true indicated torque.
struct InCycleStats {
  int n = 0;
  double rms_pct_p2p = 0.0;  ///< RMS(estimate − truth) / mean per-cycle peak-to-peak of truth × 100
  double lag_deg = 0.0;      ///< estimate behind truth at the cross-correlation maximum (deg)
  double bias_pct_p2p = 0.0;  ///< mean(estimate − truth) / p2p × 100 (the extended-load error, not the shape)
  double p2p_nm = 0.0;        ///< the mean per-cycle peak-to-peak of truth the percentages divide by (N m)
};

/// In-cycle accuracy of `est` against `truth` (same length, per tooth; `cycle`: the cycle of each sample):
/// RMS in % of the mean per-cycle peak-to-peak of truth, lag by cross-correlation (`step_deg` per sample).
[[nodiscard]] InCycleStats incycle_stats(const std::vector<double>& est, const std::vector<double>& truth,
                                         const std::vector<int>& cycle, double step_deg);

struct CylinderCaseResult {
  std::string group, name;
  int cylinders = 4;
  double mean_rpm = 0.0;
  double map_kpa = 0.0;
  std::array<double, kMaxCylinders> imbalance_est{}, imbalance_true{};
  double imbalance_max_pp = 0.0;
  /// Balanced rows at ≥ 2000 rpm (balanced_seed_row()): the same case with `seeds` simulator seeds (this
  /// row's and seeds − 1 more: edge jitter, tooth errors and the learned table are new draws); RMS and worst
  /// over the seeds of the max |error| over the cylinders (pp). seeds = 1: the single run above only.
  int seeds = 1;
  double imbalance_max_rms_pp = 0.0;
  double imbalance_max_worst_pp = 0.0;
  int misfires_true = 0, misfires_found = 0, misfires_false = 0;
  double detection_active_pct = 0.0;  ///< share of the cycles where misfire detection was possible (%)
  InCycleStats kalman, fourier;
  bool table_low_orders = false;  ///< the learner identified every per-revolution order
  double tooth_edge_resid_deg = 0.0;
};

/// The case list: simulator scenarios (imbalance, misfire, fuel_cut, three_cyl, wheel_36_1, idle), the
/// imbalance with a once-per-revolution component at 1000-4000 rpm, misfire at idle, in-cycle speed × load
/// grid, and `random_engines` engines drawn from `seed` (3/4 cylinders, 60-2/36-1, geometry, tooth errors,
/// fuel factors).
[[nodiscard]] std::vector<CylinderCase> cylinder_cases(int random_engines, std::uint64_t seed);

/// Imbalanced I4 whose imbalance has a once-per-revolution part (cylinders 1+4 against 2+3), steady at `rpm`.
[[nodiscard]] sim::Scenario once_per_rev_imbalance(int rpm, std::uint64_t seed);
/// Idle (800 rpm, declutched, idle controller) with single misfires and one cylinder misfiring every cycle.
[[nodiscard]] sim::Scenario idle_misfire(std::uint64_t seed);

/// The fuel_cut coast-down (3000 rpm, declutched) back to idle, with misfires after fuel resumes.
[[nodiscard]] sim::Scenario idle_after_cut_misfire(std::uint64_t seed);

/// Evaluate one case (tooth table learned on the warm-up recording of the same wheel, friction `friction`).
/// `seeds` > 1: a balanced row at ≥ 2000 rpm is also run on seeds − 1 more simulator seeds (imbalance only).
[[nodiscard]] CylinderCaseResult evaluate_case(const CylinderCase& c, const EvalOptions& options,
                                               int seeds = 1);

/// Rows scored over several seeds: balanced engines ("balanced", "incycle") at ≥ 2000 rpm, where one 2 s run
/// is one random draw of the jitter and the wheel.
[[nodiscard]] bool balanced_seed_row(const CylinderCase& c);

/// Filtered per-cylinder imbalance (%) at the end of `out` with the tooth widths corrected by `width_ratio`
/// (true/nominal per physical tooth).
[[nodiscard]] std::array<double, kMaxCylinders> per_cylinder_imbalance(const sim::Scenario& sc,
                                                                       const sim::SimOutput& out,
                                                                       const std::vector<double>& width_ratio,
                                                                       const EvalOptions& options);

/// Print the table (one row per case), with the column header when `header`; `seeds_column`: the multi-seed
/// column (RMS / worst / N of the max imbalance error) after "max".
void print_cylinder_table(const std::vector<CylinderCaseResult>& rows, bool header = true,
                          bool seeds_column = false);

}  // namespace torqued::eval
