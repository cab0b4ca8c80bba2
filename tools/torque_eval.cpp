// torque-eval: compares a recorded estimate CSV (torque-echo / daemon recording, first column t_ns on the
// edge clock) with the simulator's ground truth, prints a metrics table and optionally writes a PNG plot.
//   torque-eval --estimate engine_cycle.csv --truth truth_cycle.csv --column fused_nm=t_brake_mean_nm --plot
//   out.png
#include <CLI/CLI.hpp>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli_exit.hpp"
#include "evaluator.hpp"
#include "share_dir.hpp"

namespace {

bool load(const std::string& path, torqued::eval::CsvTable& t) {
  std::string error;
  std::vector<std::string> warnings;
  const bool ok = torqued::eval::read_csv(path, t, error, warnings);
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
  if (!ok) std::cerr << "error: " << error << "\n";
  return ok;
}

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

/// The command line (see add_options).
struct Args {
  std::string est_path, truth_cycle, truth_tooth, plot,
      plot_script = torqued::tools::share_path("plot_torque.py"), time_ref = "auto", title, misfire;
  std::vector<std::string> columns, where;
  torqued::eval::EvalOptions opt;
};

void add_options(CLI::App& app, Args& a) {
  app.add_option("--estimate,-e", a.est_path, "estimate CSV (header; first column t_ns)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--truth,-t", a.truth_cycle, "per-cycle truth CSV (truth_cycle.csv)")
      ->check(CLI::ExistingFile);
  app.add_option("--truth-tooth", a.truth_tooth, "per-tooth truth CSV (truth_tooth.csv)")
      ->check(CLI::ExistingFile);
  app.add_option("--column,-c", a.columns,
                 "EST=TRUTH column pair, repeatable (e.g. fused_nm=t_brake_mean_nm)")
      ->required();
  app.add_option("--where", a.where, "keep estimate rows with COL=VALUE, repeatable (e.g. method=4)");
  app.add_option("--from", a.opt.from_s, "start of the evaluated window (s, edge clock)");
  app.add_option("--to", a.opt.to_s, "end of the evaluated window (s, edge clock)");
  app.add_option("--tolerance", a.opt.tolerance,
                 "convergence tolerance on the cycle-mean error (column unit)")
      ->capture_default_str();
  app.add_option("--misfire", a.misfire,
                 "estimate misfire bit-mask column (bit i = cylinder i+1) vs truth misfire1..N");
  app.add_option(
         "--time-ref", a.time_ref,
         "estimate time matched to truth cycles: auto (the midpoint of the window the row describes: "
         "window_start_t_ns, or from the cycle column; a per-cycle join of rows without either is "
         "refused unless they come at 12 or more per cycle), sample (t_ns), mid (the window midpoint), "
         "end (t_ns closes its cycle)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "sample", "mid", "end"}));
  app.add_option("--max-lag", a.opt.max_lag_deg, "phase-lag search range (crank deg)")->capture_default_str();
  app.add_option("--plot", a.plot, "write a PNG of estimated vs true torque");
  app.add_option(
      "--plot-script", a.plot_script,
      "plot script, run with /usr/bin/python3 (default: in PREFIX/share/torqued next to PREFIX/bin)");
  app.add_option("--title", a.title, "plot title");
  app.footer(
      "Exit status: 0 done (table printed, plot written); 1 a CSV could not be read or parsed, a column is "
      "not in it (the columns that exist are listed), a per-cycle join the file cannot place (the message "
      "says which --time-ref to give), or the plot failed; 2 command-line error (unknown "
      "option, bad value, file that does not exist).");
}

/// The --time-ref, --column and --where values into `a.opt` and `pairs`; false (message printed) when one is
/// malformed.
bool parse_selections(Args& a, std::vector<torqued::eval::PairSpec>& pairs) {
  a.opt.misfire_col = a.misfire;
  a.opt.time_ref = a.time_ref == "sample" ? torqued::eval::TimeRef::kSample
                   : a.time_ref == "mid"  ? torqued::eval::TimeRef::kMid
                   : a.time_ref == "end"  ? torqued::eval::TimeRef::kEnd
                                          : torqued::eval::TimeRef::kAuto;
  for (const auto& c : a.columns) {
    auto p = torqued::eval::parse_pair(c);
    if (!p) {
      std::cerr << "error: --column '" << c << "': expected EST=TRUTH\n";
      return false;
    }
    pairs.push_back(*p);
  }
  for (const auto& w : a.where) {
    auto p = torqued::eval::parse_pair(w);
    char* end = nullptr;
    const double v = p ? std::strtod(p->truth_col.c_str(), &end) : 0.0;
    if (!p || end == nullptr || *end != '\0') {
      std::cerr << "error: --where '" << w << "': expected COL=NUMBER\n";
      return false;
    }
    a.opt.where.emplace_back(p->est_col, v);
  }
  return true;
}

/// The estimate and the truth files given; false (message printed) when one cannot be read.
bool load_inputs(const Args& a, torqued::eval::CsvTable& est, torqued::eval::Truth& truth) {
  if (!load(a.est_path, est)) return false;
  if (!a.truth_cycle.empty()) {
    truth.cycle.emplace();
    if (!load(a.truth_cycle, *truth.cycle)) return false;
  }
  if (!a.truth_tooth.empty()) {
    truth.tooth.emplace();
    if (!load(a.truth_tooth, *truth.tooth)) return false;
  }
  return true;
}

/// The PNG of --plot (plot_torque.py on the joined samples); false (message printed) when it failed.
bool write_plot(const Args& a, const torqued::eval::EvalReport& report) {
  const std::string csv = a.plot + ".data.csv";
  std::string error;
  if (!torqued::eval::write_plot_csv(report, csv, error)) {
    std::cerr << "error: " << error << "\n";
    return false;
  }
  // Debian's python3-matplotlib lives with /usr/bin/python3 (the PATH python may be another one).
  const std::string cmd = "/usr/bin/python3 " + shell_quote(a.plot_script) + " --data " + shell_quote(csv) +
                          " --out " + shell_quote(a.plot) +
                          (a.title.empty() ? "" : " --title " + shell_quote(a.title));
  const int rc = std::system(cmd.c_str());
  std::error_code ec;
  std::filesystem::remove(csv, ec);
  if (rc != 0) {
    std::cerr << "error: plot failed (" << cmd << ")\n";
    return false;
  }
  std::cout << "plot: " << a.plot << "\n";
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"torque-eval: error metrics of a torque estimate against the simulator's ground truth"};
  Args a;
  add_options(app, a);
  TORQUED_CLI_PARSE(app, argc, argv);
  if (a.truth_cycle.empty() && a.truth_tooth.empty()) {
    std::cerr << "error: give --truth (truth_cycle.csv) and/or --truth-tooth (truth_tooth.csv)\n";
    return 2;
  }
  std::vector<torqued::eval::PairSpec> pairs;
  if (!parse_selections(a, pairs)) return 2;
  torqued::eval::CsvTable est;
  torqued::eval::Truth truth;
  if (!load_inputs(a, est, truth)) return 1;
  torqued::eval::EvalReport report;
  std::string error;
  if (!torqued::eval::evaluate(est, truth, pairs, a.opt, report, error)) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  std::cout << torqued::eval::format_report(report, a.opt.tolerance);
  for (const auto& p : report.pairs)
    if (p.stats.n == 0)
      std::cerr << "warning: no joined samples for " << p.spec.est_col << " = " << p.spec.truth_col
                << " (check the time window and time_offset)\n";
  if (!a.plot.empty() && !write_plot(a, report)) return 1;
  return 0;
}
