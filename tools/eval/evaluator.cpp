#include "evaluator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace torqued::eval {
namespace {

/// Index of the truth cycle containing t ([t_start, t_end), or (t_start, t_end] when end_closed); -1 if none.
long find_cycle(const std::vector<double>& t0, const std::vector<double>& t1, double t, bool end_closed) {
  auto it =
      end_closed ? std::lower_bound(t0.begin(), t0.end(), t) : std::upper_bound(t0.begin(), t0.end(), t);
  if (it == t0.begin()) return -1;
  const std::size_t c = static_cast<std::size_t>(it - t0.begin()) - 1;
  const bool inside = end_closed ? (t > t0[c] && t <= t1[c]) : (t >= t0[c] && t < t1[c]);
  return inside ? static_cast<long>(c) : -1;
}

/// "a, b, c": the header of a CSV, for messages naming a column that is not there.
std::string join_names(const CsvTable& t) {
  std::string out;
  for (const auto& n : t.names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? "(none)" : out;
}

std::string fmt(double v, int prec = 3) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  const double a = std::abs(v);
  if (a != 0.0 && (a >= 1e6 || a < 1e-3))
    std::snprintf(buf, sizeof buf, "%.*e", prec - 1, v);
  else
    std::snprintf(buf, sizeof buf, "%.*f", prec, v);
  return buf;
}

/// The estimate rows, their times and the truth tables, checked once; shared by every pair and the misfire
/// count.
struct Joined {
  const CsvTable& est;
  std::vector<double> t;    ///< estimate time on the edge clock (s)
  std::vector<double> ws;   ///< start of the window each row describes (s; NaN: unknown); empty: none
  bool ws_derived = false;  ///< ws from the cycle column (the previous cycle's row), not window_start_t_ns
  std::vector<std::size_t> rows;  ///< rows kept by --where/--from/--to
  TimeRef ref = TimeRef::kSample;
  bool ref_guessed = false;       ///< --time-ref auto fell back to the sample time (no window in the file)
  const CsvTable* cyc = nullptr;  ///< truth cycles
  std::vector<double> c_t0, c_t1, c_num;
  const CsvTable* tooth = nullptr;  ///< truth teeth
  std::vector<double> tt, tang;     ///< truth tooth time and unwrapped angle

  explicit Joined(const CsvTable& e) : est(e) {}

  /// Truth cycle of estimate row i (-1 if none), with the row's time taken as the time reference says.
  [[nodiscard]] long cycle_of(std::size_t i) const {
    if (!cyc) return -1;
    double tq = t[i];
    if (ref == TimeRef::kMid) {
      const double w = ws[i];
      if (std::isfinite(w) && w >= 0.0 && w < t[i])
        tq = 0.5 * (w + t[i]);
      else if (ws_derived)
        return -1;  // the first cycle of a record: where its window starts is not in the file
      // else: a row without a window (window_start_t_ns not before t_ns): its sample time
    }
    if (ref == TimeRef::kEnd) {
      // The row closes a cycle whose boundaries need not match the truth's: step back half a cycle.
      long c = find_cycle(c_t0, c_t1, tq, false);
      if (c < 0) c = find_cycle(c_t0, c_t1, tq, true);
      if (c < 0) return -1;
      tq -= 0.5 * (c_t1[std::size_t(c)] - c_t0[std::size_t(c)]);
    }
    return find_cycle(c_t0, c_t1, tq, false);
  }
};

/// Window starts of a record with a cycle column and no window_start_t_ns (cylinder_torque.csv): cycle n of
/// an engine starts where that engine's row(s) of cycle n-1 end (the last such row before it in the file).
std::vector<double> windows_from_cycles(const CsvTable& est, const std::vector<double>& t, int c_cycle) {
  const int c_engine = est.column("engine_id");
  std::map<std::pair<double, double>, double> end_of;  // (engine, cycle) -> t of its last row so far
  std::vector<double> ws(t.size(), std::nan(""));
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double engine = c_engine >= 0 ? est.col(c_engine)[i] : 0.0;
    const double cycle = est.col(c_cycle)[i];
    if (!std::isfinite(cycle) || !std::isfinite(t[i])) continue;
    const auto prev = end_of.find({engine, cycle - 1.0});
    if (prev != end_of.end()) ws[i] = prev->second;
    end_of[{engine, cycle}] = t[i];
  }
  return ws;
}

/// The time reference: the window the row describes when the file says it (window_start_t_ns, else the cycle
/// column), else the sample time (checked in refuse_guessed_join before a per-cycle join).
bool resolve_time_ref(Joined& j, TimeRef asked, std::string& error) {
  const CsvTable& est = j.est;
  const int c_ws = est.column("window_start_t_ns"), c_cycle = est.column("cycle");
  if (c_ws >= 0) {
    j.ws.resize(est.rows());
    for (std::size_t i = 0; i < est.rows(); ++i) j.ws[i] = est.col(c_ws)[i] * 1e-9;
  } else if (c_cycle >= 0) {
    j.ws = windows_from_cycles(est, j.t, c_cycle);
    j.ws_derived = true;
  }
  j.ref = asked;
  if (asked == TimeRef::kAuto) {
    j.ref = j.ws.empty() ? TimeRef::kSample : TimeRef::kMid;
    j.ref_guessed = j.ws.empty();
  }
  if (j.ref == TimeRef::kMid && j.ws.empty()) {
    error = est.path + ": --time-ref mid needs a window_start_t_ns or a cycle column";
    return false;
  }
  return true;
}

bool join_times(Joined& j, const EvalOptions& opt, std::string& error) {
  const CsvTable& est = j.est;
  const int c_tns = est.column("t_ns"), c_ts = est.column("t_s");
  if (c_tns < 0 && c_ts < 0) {
    error = est.path + ": no t_ns (or t_s) column; columns are the header of the estimate CSV";
    return false;
  }
  j.t.resize(est.rows());
  for (std::size_t i = 0; i < est.rows(); ++i)
    j.t[i] = c_tns >= 0 ? est.col(c_tns)[i] * 1e-9 : est.col(c_ts)[i];
  if (!resolve_time_ref(j, opt.time_ref, error)) return false;
  std::vector<std::pair<int, double>> where;
  for (const auto& [name, value] : opt.where) {
    const int c = est.column(name);
    if (c < 0) {
      error = est.path + ": --where column '" + name + "' not found; its columns are: " + join_names(est);
      return false;
    }
    where.emplace_back(c, value);
  }
  for (std::size_t i = 0; i < est.rows(); ++i) {
    if (!std::isfinite(j.t[i]) || j.t[i] < opt.from_s || j.t[i] > opt.to_s) continue;
    bool keep = true;
    for (const auto& [c, v] : where) keep = keep && est.col(c)[i] == v;
    if (keep) j.rows.push_back(i);
  }
  return true;
}

/// A per-cycle join at the sample time is right for instantaneous values (per tooth: dozens of rows per
/// cycle) and wrong for values that average a window closing at t_ns (per cycle or per segment: a window that
/// ends at a cycle boundary would be credited to the next cycle). Without a window in the file, --time-ref
/// auto refuses the latter instead of guessing.
bool refuse_guessed_join(const Joined& j, const std::string& what, std::string& error) {
  if (!j.ref_guessed || !j.cyc) return false;
  std::map<long, std::size_t> per_cycle;
  for (std::size_t i : j.rows) {
    const long c = j.cycle_of(i);
    if (c >= 0) ++per_cycle[c];
  }
  std::size_t n = 0;
  for (const auto& [c, k] : per_cycle) n += k;
  constexpr double kMinInstantRowsPerCycle = 12.0;  // a tooth wheel has more; 8 cylinders' segments fewer
  const double rate =
      per_cycle.empty() ? 0.0 : static_cast<double>(n) / static_cast<double>(per_cycle.size());
  if (per_cycle.empty() || rate >= kMinInstantRowsPerCycle) return false;
  error =
      j.est.path + ": " + what + " needs the window each row describes, and the file has neither " +
      "window_start_t_ns nor a cycle column (" + fmt(rate, 1) +
      " rows per truth cycle: per-cycle or per-segment values). Say what t_ns is: --time-ref end (the row " +
      "closes its cycle) or --time-ref sample (an instantaneous value)";
  return true;
}

bool join_truth(Joined& j, const Truth& truth, std::string& error) {
  j.cyc = truth.cycle ? &*truth.cycle : nullptr;
  if (j.cyc) {
    const int a = j.cyc->column("t_start_s"), b = j.cyc->column("t_end_s"), n = j.cyc->column("cycle");
    if (a < 0 || b < 0) {
      error = j.cyc->path + ": needs t_start_s and t_end_s columns";
      return false;
    }
    j.c_t0 = j.cyc->col(a);
    j.c_t1 = j.cyc->col(b);
    j.c_num = n >= 0 ? j.cyc->col(n) : std::vector<double>{};
  }
  j.tooth = truth.tooth ? &*truth.tooth : nullptr;
  if (!j.tooth) return true;
  const int c = j.tooth->column("t_s");
  if (c < 0) {
    error = j.tooth->path + ": needs a t_s column";
    return false;
  }
  j.tt = j.tooth->col(c);
  const int ca = j.tooth->column("angle720_deg");
  if (ca >= 0) {  // unwrap the 720° angle
    const auto& raw = j.tooth->col(ca);
    j.tang = raw;
    double offset = 0.0;
    for (std::size_t k = 1; k < j.tang.size(); ++k) {
      if (raw[k] + offset < j.tang[k - 1] - 360.0) offset += 720.0;
      j.tang[k] = raw[k] + offset;
    }
  }
  return true;
}

/// Per-cycle means and the convergence of their error (or per sample without cycle truth).
void cycle_means(const Joined& j, const EvalOptions& opt,
                 const std::map<long, std::pair<double, double>>& est_sum,
                 std::map<long, std::pair<double, double>>& truth_sum, PairResult& r) {
  std::vector<double> em, tm, cerr;
  std::vector<long> cid;
  for (const auto& [c, s] : est_sum) {
    em.push_back(s.first / s.second);
    tm.push_back(truth_sum[c].first / truth_sum[c].second);
    cerr.push_back(em.back() - tm.back());
    cid.push_back(c);
  }
  r.cycles = em.size();
  r.cycle_pct = cycle_mean_pct_error(em, tm);
  if (!cerr.empty()) {
    const std::size_t k = convergence_index(cerr, opt.tolerance);
    if (k < cerr.size()) {
      const auto c = static_cast<std::size_t>(cid[k]);
      r.converged_cycle = j.c_num.empty() ? c : static_cast<std::size_t>(j.c_num[c]);
      r.converged_t_s = j.c_t0[c];
    }
  } else if (!r.est.empty()) {  // no cycle truth: convergence per sample
    std::vector<double> err(r.est.size());
    for (std::size_t i = 0; i < err.size(); ++i) err[i] = r.est[i] - r.truth[i];
    const std::size_t k = convergence_index(err, opt.tolerance);
    if (k < err.size()) r.converged_t_s = r.t_s[k];
  }
}

bool evaluate_pair(const Joined& j, const PairSpec& p, const EvalOptions& opt, PairResult& r,
                   std::string& error) {
  r.spec = p;
  const CsvTable& est = j.est;
  const int ce = est.column(p.est_col);
  if (ce < 0) {
    error = est.path + ": estimate column '" + p.est_col + "' not found; its columns are: " + join_names(est);
    return false;
  }
  const int cc = j.cyc ? j.cyc->column(p.truth_col) : -1;
  const int ct = j.tooth ? j.tooth->column(p.truth_col) : -1;
  if (cc < 0 && ct < 0) {
    error = "truth column '" + p.truth_col + "' is in neither " + (j.cyc ? j.cyc->path : "(no --truth)") +
            " nor " + (j.tooth ? j.tooth->path : "(no --truth-tooth)");
    if (j.cyc) error += "\n  " + j.cyc->path + " columns: " + join_names(*j.cyc);
    if (j.tooth) error += "\n  " + j.tooth->path + " columns: " + join_names(*j.tooth);
    return false;
  }
  r.per_cycle = cc >= 0;
  if (r.per_cycle && refuse_guessed_join(j, "the per-cycle join of " + p.est_col, error)) return false;
  std::map<long, std::pair<double, double>> est_sum, truth_sum;  // cycle → (sum, count) in time order
  std::vector<double> est_angle;
  for (std::size_t i : j.rows) {
    const double e = est.col(ce)[i];
    const long c = j.cycle_of(i);
    const double y = r.per_cycle ? (c >= 0 ? j.cyc->col(cc)[std::size_t(c)] : std::nan(""))
                                 : interpolate(j.tt, j.tooth->col(ct), j.t[i]);
    if (!std::isfinite(e) || !std::isfinite(y)) continue;
    r.t_s.push_back(j.t[i]);
    r.est.push_back(e);
    r.truth.push_back(y);
    if (!j.tang.empty()) est_angle.push_back(interpolate(j.tt, j.tang, j.t[i]));
    if (c >= 0) {
      est_sum[c].first += e;
      est_sum[c].second += 1;
      truth_sum[c].first += y;
      truth_sum[c].second += 1;
    }
  }
  r.stats = error_stats(r.t_s, r.est, r.truth);
  cycle_means(j, opt, est_sum, truth_sum, r);
  if (!r.per_cycle && !j.tang.empty()) {
    // In-cycle phase lag: truth on its angle grid vs estimate at the angles of its samples.
    std::vector<double> ea, ev;
    for (std::size_t i = 0; i < est_angle.size(); ++i)
      if (std::isfinite(est_angle[i])) {
        ea.push_back(est_angle[i]);
        ev.push_back(r.est[i]);
      }
    r.lag = phase_lag(ea, ev, j.tang, j.tooth->col(ct), opt.max_lag_deg);
  }
  return true;
}

bool evaluate_misfire(const Joined& j, const std::string& col, EvalReport& report, std::string& error) {
  const int cm = j.est.column(col);
  if (cm < 0) {
    error = j.est.path + ": misfire column '" + col + "' not found; its columns are: " + join_names(j.est);
    return false;
  }
  if (!j.cyc) {
    error = "--misfire needs --truth (truth_cycle.csv with misfire1..N)";
    return false;
  }
  std::vector<int> truth_cols;
  for (int k = 1; k <= 8; ++k) {
    const int c = j.cyc->column("misfire" + std::to_string(k));
    if (c < 0) break;
    truth_cols.push_back(c);
  }
  if (truth_cols.empty()) {
    error = j.cyc->path + ": no misfire1.. columns";
    return false;
  }
  if (refuse_guessed_join(j, "--misfire", error)) return false;
  std::map<long, std::uint32_t> masks;  // OR of the masks of the rows in each truth cycle
  for (std::size_t i : j.rows) {
    const long c = j.cycle_of(i);
    const double m = j.est.col(cm)[i];
    if (c >= 0 && std::isfinite(m)) masks[c] |= static_cast<std::uint32_t>(m);
  }
  MisfireStats s;
  for (const auto& [c, mask] : masks) {
    std::vector<bool> flags;
    for (int col_k : truth_cols) flags.push_back(j.cyc->col(col_k)[std::size_t(c)] > 0.5);
    count_misfires(flags, mask, s);
  }
  report.misfire = s;
  return true;
}

}  // namespace

std::optional<PairSpec> parse_pair(const std::string& s) {
  const auto eq = s.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == s.size()) return std::nullopt;
  return PairSpec{s.substr(0, eq), s.substr(eq + 1)};
}

bool evaluate(const CsvTable& est, const Truth& truth, const std::vector<PairSpec>& pairs,
              const EvalOptions& opt, EvalReport& report, std::string& error) {
  report = EvalReport{};
  report.est_rows = est.rows();
  Joined j(est);
  if (!join_times(j, opt, error)) return false;
  report.rows_used = j.rows.size();
  if (!join_truth(j, truth, error)) return false;
  for (const auto& p : pairs) {
    PairResult r;
    if (!evaluate_pair(j, p, opt, r, error)) return false;
    report.pairs.push_back(std::move(r));
  }
  return opt.misfire_col.empty() || evaluate_misfire(j, opt.misfire_col, report, error);
}

std::string format_report(const EvalReport& r, double tolerance) {
  std::ostringstream os;
  os << "estimate rows: " << r.est_rows << ", used: " << r.rows_used << "\n";
  char line[512];
  std::snprintf(line, sizeof line, "%-34s %-5s %7s %9s %9s %9s %9s %11s %8s %8s %9s\n", "estimate = truth",
                "join", "N", "bias", "RMS", "max|err|", "SD", "ISE", "cyc%err", "lag_deg", "conv_cyc");
  os << line;
  for (const auto& p : r.pairs) {
    const std::string name = p.spec.est_col + " = " + p.spec.truth_col;
    const std::string conv =
        p.converged_cycle ? std::to_string(*p.converged_cycle)
                          : (std::isfinite(p.converged_t_s) ? "t=" + fmt(p.converged_t_s, 2) : "never");
    std::snprintf(line, sizeof line, "%-34s %-5s %7zu %9s %9s %9s %9s %11s %8s %8s %9s\n", name.c_str(),
                  p.per_cycle ? "cycle" : "tooth", p.stats.n, fmt(p.stats.bias).c_str(),
                  fmt(p.stats.rms).c_str(), fmt(p.stats.mae).c_str(), fmt(p.stats.sd).c_str(),
                  fmt(p.stats.ise).c_str(), fmt(p.cycle_pct, 2).c_str(),
                  p.lag && p.lag->ok ? fmt(p.lag->lag_deg, 1).c_str() : "-", conv.c_str());
    os << line;
  }
  os << "bias/RMS/max|err|/SD in the columns' unit (max|err| = largest absolute error, the papers' \"MAE\"), "
        "ISE in "
        "unit^2 s,\ncyc%err = 100 sum|mean err|/sum|mean truth| per cycle,\n"
        "lag > 0: estimate lags truth (crank deg), conv_cyc: truth cycle after which |cycle-mean error| <= "
     << tolerance << "\n";
  if (r.misfire) {
    const auto& m = *r.misfire;
    os << "misfire: " << m.true_misfires << " true, " << m.detected << " detected (recall "
       << fmt(100.0 * m.recall(), 1) << " %), " << m.false_alarms << " false alarms in " << m.cylinder_cycles
       << " cylinder-cycles\n";
  }
  for (const auto& n : r.notes) os << "note: " << n << "\n";
  return os.str();
}

bool write_plot_csv(const EvalReport& r, const std::string& path, std::string& error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) {
    error = path + ": cannot write";
    return false;
  }
  std::fprintf(f, "pair,t_s,est,truth\n");
  for (const auto& p : r.pairs) {
    const std::string name = p.spec.est_col + " vs " + p.spec.truth_col;
    for (std::size_t i = 0; i < p.t_s.size(); ++i)
      std::fprintf(f, "%s,%.9f,%.6g,%.6g\n", name.c_str(), p.t_s[i], p.est[i], p.truth[i]);
  }
  const bool ok = std::fclose(f) == 0;
  if (!ok) error = path + ": write failed";
  return ok;
}

}  // namespace torqued::eval
