#pragma once
// torque-eval's core: joins an estimate CSV (first column t_ns on the edge clock) with the simulator's truth
// (truth_cycle.csv: cycle,t_start_s,t_end_s,...; truth_tooth.csv: t_s,tooth,angle720_deg,...) and computes
// the metrics of metrics.hpp per column pair.
//   per-cycle join: the truth column is in truth_cycle.csv → the cycle whose [t_start, t_end) contains the
//                   midpoint of the window the row describes (window_start_t_ns, or from the cycle column;
//                   see TimeRef); a join the file cannot place (no window, few rows per cycle) is refused;
//   per-tooth join: the truth column is in truth_tooth.csv → linear interpolation at the estimate time.
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "csv_table.hpp"
#include "metrics.hpp"

namespace torqued::eval {

struct Truth {
  std::optional<CsvTable> cycle;  ///< truth_cycle.csv
  std::optional<CsvTable> tooth;  ///< truth_tooth.csv
};

struct PairSpec {
  std::string est_col;
  std::string truth_col;
};
/// "fused_nm=t_brake_mean_nm" → {fused_nm, t_brake_mean_nm}; nullopt if malformed.
[[nodiscard]] std::optional<PairSpec> parse_pair(const std::string& s);

/// Which time of an estimate row is matched against the truth cycles.
enum class TimeRef {
  kAuto,    ///< kMid when the file gives windows, else kSample for per-tooth rows (per-cycle rows: refused)
  kSample,  ///< t_ns as is
  kMid,     ///< window midpoint: (window_start_t_ns + t_ns)/2, or without that column (cylinder_torque.csv)
            ///< the window from the end of the same engine's previous cycle (cycle column) to t_ns
  kEnd,     ///< t_ns closes its cycle (e.g. cylinder_torque.csv): matched at t_ns minus half a truth cycle
};

struct EvalOptions {
  double from_s = -std::numeric_limits<double>::infinity();  ///< edge-clock window (s)
  double to_s = std::numeric_limits<double>::infinity();
  double tolerance = 5.0;  ///< convergence tolerance on the per-cycle mean error (unit of the columns)
  std::vector<std::pair<std::string, double>>
      where;                ///< keep estimate rows with col == value (e.g. method=4)
  std::string misfire_col;  ///< estimate bit-mask column (bit i = cylinder i+1) vs truth misfire1..N
  TimeRef time_ref = TimeRef::kAuto;
  double max_lag_deg = 90.0;
};

struct PairResult {
  PairSpec spec;
  bool per_cycle = true;  ///< join kind
  ErrorStats stats;
  std::size_t cycles = 0;  ///< cycles with at least one sample
  double cycle_pct = std::numeric_limits<double>::quiet_NaN();
  std::optional<PhaseLag> lag;  ///< per-tooth joins with angle720_deg in the tooth truth
  std::optional<std::size_t>
      converged_cycle;  ///< truth cycle number after which the cycle-mean error stays in tolerance
  double converged_t_s = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> t_s, est, truth;  ///< joined samples (for the plot)
};

struct EvalReport {
  std::size_t est_rows = 0, rows_used = 0;  ///< after where/from/to filtering
  std::vector<PairResult> pairs;
  std::optional<MisfireStats> misfire;
  std::vector<std::string> notes;
};

/// Returns false with `error` (naming the file and column) when a column or the needed truth is missing.
bool evaluate(const CsvTable& est, const Truth& truth, const std::vector<PairSpec>& pairs,
              const EvalOptions& opt, EvalReport& report, std::string& error);

/// The printed table (one row per pair, then misfire counts).
[[nodiscard]] std::string format_report(const EvalReport& r, double tolerance);

/// Long-format CSV for plot_torque.py: pair,t_s,est,truth.
bool write_plot_csv(const EvalReport& r, const std::string& path, std::string& error);

}  // namespace torqued::eval
