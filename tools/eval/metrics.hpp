#pragma once
// Error metrics of an estimate against truth (docs/equations.md §1.5, Na-60..62: ISE = ∫ε² dt, MAE = max|ε|,
// SD = std(ε)), cycle-mean % error, in-cycle phase lag by cross-correlation, convergence and misfire counts.
// Pure functions on vectors; NaN inputs are the caller's business (filter them first).
#include <cstddef>
#include <cstdint>
#include <vector>

namespace torqued::eval {

struct ErrorStats {
  std::size_t n = 0;
  double bias = 0.0;  ///< mean ε
  double rms = 0.0;   ///< sqrt(mean ε²)
  double mae = 0.0;   ///< max |ε| (the papers' "MAE", Na-61)
  double sd = 0.0;    ///< standard deviation of ε (population, Na-62)
  double ise = 0.0;   ///< ∫ ε² dt, trapezoidal over the sample times (Na-60) (unit² · s)
};

/// ε_i = est_i − truth_i at times t_s (ascending).
[[nodiscard]] ErrorStats error_stats(const std::vector<double>& t_s, const std::vector<double>& est,
                                     const std::vector<double>& truth);

/// 100 · Σ_c |ē_c − t̄_c| / Σ_c |t̄_c| over cycle means (robust to cycles with a mean near zero). NaN if empty.
[[nodiscard]] double cycle_mean_pct_error(const std::vector<double>& est_means,
                                          const std::vector<double>& truth_means);

/// Index of the first element after which |e| stays <= tol for good; size() when never.
[[nodiscard]] std::size_t convergence_index(const std::vector<double>& err, double tol);

struct PhaseLag {
  bool ok = false;
  double lag_deg = 0.0;      ///< > 0: the estimate lags the truth (est(θ) ≈ truth(θ − lag))
  double correlation = 0.0;  ///< Pearson correlation at the best lag
};

/// Cross-correlation in the crank-angle domain. `est_angle_deg` are the (unwrapped, ascending) crank angles
/// of the estimate samples; truth is given on its own ascending angle grid. Lags in [-max_lag_deg,
/// max_lag_deg] by step_deg, refined by a parabola through the best three.
[[nodiscard]] PhaseLag phase_lag(const std::vector<double>& est_angle_deg, const std::vector<double>& est,
                                 const std::vector<double>& truth_angle_deg, const std::vector<double>& truth,
                                 double max_lag_deg = 90.0, double step_deg = 0.5);

/// Linear interpolation of y(x) at xq (x ascending); NaN outside [x.front(), x.back()].
[[nodiscard]] double interpolate(const std::vector<double>& x, const std::vector<double>& y, double xq);

struct MisfireStats {
  std::size_t cylinder_cycles = 0;  ///< (cycle, cylinder) pairs compared
  std::size_t true_misfires = 0;
  std::size_t detected = 0;      ///< true misfires flagged
  std::size_t false_alarms = 0;  ///< flagged without a true misfire
  [[nodiscard]] double recall() const noexcept {
    return true_misfires ? static_cast<double>(detected) / static_cast<double>(true_misfires) : 1.0;
  }
};

/// One cycle: truth flags per cylinder, estimated bit mask (bit i = cylinder i+1).
void count_misfires(const std::vector<bool>& truth, std::uint32_t est_mask, MisfireStats& s);

}  // namespace torqued::eval
