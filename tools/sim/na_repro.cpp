#include "na_repro.hpp"

#include <cmath>
#include <cstdio>
#include <functional>

#include "adaptive_tv.hpp"
#include "dirty_diff.hpp"
#include "sliding_mode.hpp"
#include "time_sample.hpp"
#include "uio.hpp"

namespace torqued::sim {

ErrorMetrics error_metrics(const std::vector<NaScenarioSample>& samples, const std::vector<double>& est,
                           double start_s, double end_s) {
  ErrorMetrics m;
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i + 1 < samples.size() && i < est.size(); ++i) {
    const double t = samples[i].t_s;
    if (t < start_s || t > end_s) continue;
    const double dt = samples[i + 1].t_s - t;
    const double e = samples[i].true_torque_nm - est[i];
    m.ise += e * e * dt;
    m.mae = std::max(m.mae, std::abs(e));
    sum += e;
    sum2 += e * e;
    ++n;
  }
  if (n > 0) {
    m.mean = sum / static_cast<double>(n);
    m.sd = std::sqrt(std::max(0.0, sum2 / static_cast<double>(n) - m.mean * m.mean));
  }
  return m;
}

namespace {
TimeSample to_time_sample(const NaScenarioSample& s, double dt) {
  TimeSample ts;
  ts.t_ns = std::llround(s.t_s * 1e9);
  ts.dt_s = dt;
  ts.speed_rad_s = s.speed_rad_s;
  ts.load_torque_nm = s.load_nm;
  ts.maf_kg_s = s.maf_kg_s;
  ts.speed = ts.load = ts.maf = InputStatus::kOk;
  return ts;
}

template <typename Est>
NaMethodResult run_one(const std::string& name, Est est, const std::vector<NaScenarioSample>& samples,
                       const NaReproConfig& cfg) {
  NaMethodResult r;
  r.name = name;
  r.torque_nm.reserve(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double dt = i + 1 < samples.size() ? samples[i + 1].t_s - samples[i].t_s
                                             : (i > 0 ? samples[i].t_s - samples[i - 1].t_s : 0.001);
    est.update(to_time_sample(samples[i], dt));
    r.torque_nm.push_back(est.estimate().torque_nm);
  }
  r.metrics = error_metrics(samples, r.torque_nm, cfg.window_start_s, cfg.window_end_s);
  return r;
}
}  // namespace

std::vector<NaMethodResult> run_na_methods(const std::vector<NaScenarioSample>& samples,
                                           const NaReproConfig& cfg) {
  const double step = samples.size() > 1 ? samples[1].t_s - samples[0].t_s : 0.001;
  std::vector<NaMethodResult> out;
  out.push_back(run_one("uio", Uio(cfg.uio, cfg.inertia_kgm2, step), samples, cfg));
  out.push_back(run_one("sliding_mode", SlidingMode(cfg.sliding, cfg.inertia_kgm2, step), samples, cfg));
  out.push_back(run_one("dirty_diff", DirtyDiff(cfg.dirty, cfg.inertia_kgm2, step), samples, cfg));
  for (const bool tv : {false, true}) {
    for (const double kappa : {0.0, 0.1}) {
      AdaptiveParams p = cfg.adaptive;
      p.time_varying_gain = tv;
      p.kappa = kappa;
      char name[32];
      std::snprintf(name, sizeof name, "law%d_kappa%.1f", tv ? 54 : 50, kappa);
      out.push_back(run_one(name, AdaptiveTv(p, cfg.inertia_kgm2, step), samples, cfg));
    }
  }
  return out;
}

std::string format_na_tables(const std::vector<NaMethodResult>& results) {
  auto find = [&](const std::string& n) -> const ErrorMetrics* {
    for (const auto& r : results) {
      if (r.name == n) return &r.metrics;
    }
    return nullptr;
  };
  std::string s;
  char line[256];
  auto row = [&](const char* label, const std::vector<const ErrorMetrics*>& ms,
                 const std::function<double(const ErrorMetrics&)>& get, const char* fmt) {
    std::snprintf(line, sizeof line, "%-6s", label);
    s += line;
    for (const auto* m : ms) {
      std::snprintf(line, sizeof line, fmt, m ? get(*m) : NAN);
      s += line;
    }
    s += "\n";
  };
  const std::vector<const ErrorMetrics*> t3{find("uio"), find("sliding_mode"), find("dirty_diff")};
  s += "TABLE III. Torque estimation performance indices (window 5-30 s)\n";
  s += "Index        UIO (14)  Sliding mode (21)  Dirty diff. (24)\n";
  row(
      "ISE", t3, [](const ErrorMetrics& m) { return m.ise; }, " %16.4e");
  row(
      "MAE", t3, [](const ErrorMetrics& m) { return m.mae; }, " %16.4f");
  row(
      "SD", t3, [](const ErrorMetrics& m) { return m.sd; }, " %16.4f");
  const std::vector<const ErrorMetrics*> t4{find("law50_kappa0.0"), find("law50_kappa0.1"),
                                            find("law54_kappa0.0"), find("law54_kappa0.1")};
  s += "\nTABLE IV. Adaptive laws (window 5-30 s)\n";
  s += "             Constant gain (50)                  Time-varying gain (54)\n";
  s += "Index      kappa=0       kappa=0.1          kappa=0       kappa=0.1\n";
  row(
      "ISE", t4, [](const ErrorMetrics& m) { return m.ise; }, " %16.4e");
  row(
      "MAE", t4, [](const ErrorMetrics& m) { return m.mae; }, " %16.4f");
  row(
      "SD", t4, [](const ErrorMetrics& m) { return m.sd; }, " %16.4f");
  return s;
}

}  // namespace torqued::sim
