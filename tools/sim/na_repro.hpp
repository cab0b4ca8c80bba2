#pragma once
// Runs the time-triggered estimators of Na et al. on a mean-value scenario and scores them with the paper's
// indices (Na-60..62) over a window (paper: 5-30 s). Shared by tools/torque_na_repro.cpp and its ctest.
#include <string>
#include <vector>

#include "mean_value_engine.hpp"
#include "params.hpp"

namespace torqued::sim {

struct ErrorMetrics {
  double ise = 0.0;   ///< ∫ε² dt over the window (N² m² s) (Na-60)
  double mae = 0.0;   ///< max|ε| (N m) (Na-61)
  double sd = 0.0;    ///< standard deviation of ε (N m) (Na-62)
  double mean = 0.0;  ///< mean of ε (N m)
};

struct NaMethodResult {
  std::string name;  ///< e.g. "uio", "sliding_mode", "law50_k0"
  ErrorMetrics metrics;
  std::vector<double> torque_nm;  ///< estimate per sample
};

struct NaReproConfig {
  UioParams uio{};
  SlidingModeParams sliding{.k_s = 0.01, .lambda1_nm = 150.0};  ///< Na §VI simulation: λ1 = 150
  DirtyDiffParams dirty{};
  AdaptiveParams adaptive{};   ///< law and κ are overridden per method
  double inertia_kgm2 = 0.14;  ///< J used by the estimators (the model's J)
  double window_start_s = 5.0;
  double window_end_s = 30.0;
};

/// ε = truth − estimate over [start, end]; rectangle rule with the sample step.
[[nodiscard]] ErrorMetrics error_metrics(const std::vector<NaScenarioSample>& samples,
                                         const std::vector<double>& est, double start_s, double end_s);

/// UIO, sliding mode, dirty differentiation, then the adaptive laws (50) and (54) each with κ = 0 and 0.1.
[[nodiscard]] std::vector<NaMethodResult> run_na_methods(const std::vector<NaScenarioSample>& samples,
                                                         const NaReproConfig& cfg);

/// The table in the layout of Na 2017 Tables III and IV (plain text, fixed width).
[[nodiscard]] std::string format_na_tables(const std::vector<NaMethodResult>& results);

}  // namespace torqued::sim
