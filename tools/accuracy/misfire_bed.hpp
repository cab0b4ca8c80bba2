#pragma once
// Misfire detection and per-cylinder imbalance across the speed range on the unseen-engines bed
// (unseen_engines.hpp): each engine configured from its spec sheet only (generic friction prior), its wheel
// learned on the warm-up recording of the same wheel (pipeline_eval.hpp, warmup_scenario()), then
//   idle  800 rpm, declutched, the idle controller holding speed on a base throttle (low torque)
//   mid   2500 rpm, 60 kPa, dyno-held
//   high  6000 rpm, 80 kPa, dyno-held
// each with two single misfires, a pair in one cycle (two cylinders next to each other in the firing order)
// and a pair of consecutive cycles on one cylinder; plus "weak": one cylinder at 85 % fuel, 2200 rpm 60 kPa,
// scored on the filtered per-cylinder imbalance. Misfires are matched per cycle and cylinder
// (evaluate(): found / true / false). Not real-time code.
#include <string>
#include <vector>

#include "pipeline_eval.hpp"
#include "unseen_engines.hpp"

namespace torqued::eval {

/// One scenario of the misfire bed on one engine.
struct MisfireBedRow {
  std::string engine, regime;  ///< regime: "idle", "mid", "high", "weak"
  bool report = false;
  double mean_rpm = 0.0;
  int found = 0, truth = 0, false_alarms = 0;
  double detection_active_pct = 0.0;  ///< cycles where detection was possible (%)
  double imbalance_rms_pp = 0.0;      ///< RMS over the cylinders of filtered − true imbalance (pp)
  double imbalance_max_pp = 0.0;      ///< largest |filtered − true| over the cylinders (pp)
};

/// The scenario of `regime` ("idle", "mid", "high", "weak") on `engine` (2.5-5 s each: cheap enough that the
/// ctest runs the whole bed on the report engines).
[[nodiscard]] sim::Scenario misfire_bed_scenario(const sim::BedEngine& engine, const std::string& regime);
/// Evaluate one regime on one engine.
[[nodiscard]] MisfireBedRow evaluate_misfire_bed(const sim::BedEngine& engine, const std::string& regime,
                                                 const EvalOptions& options);
/// The regimes in table order.
[[nodiscard]] const std::vector<std::string>& misfire_bed_regimes();

}  // namespace torqued::eval
