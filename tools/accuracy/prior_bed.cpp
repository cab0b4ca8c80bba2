// torque-accuracy --bed-priors (daemon_bed.hpp run_bed_priors): how far the generic priors sit from engines,
// per engine and pooled over the calibration engines (the set that fixes the priors' 1σ defaults), the bed's
// tuning and its report engines; docs/angle_pipeline.md "Calibrating the priors".
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "daemon_bed.hpp"

namespace torqued::eval {
namespace {
/// The q-quantile of |v| (0 when empty).
double abs_quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  for (double& x : v) x = std::fabs(x);
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)))];
}
double rms_of(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / static_cast<double>(v.size()));
}
/// Pearson correlation of a and b (same length; 0 when undefined).
double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const std::size_t n = std::min(a.size(), b.size());
  if (n < 2) return 0.0;
  double ma = 0.0, mb = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= static_cast<double>(n);
  mb /= static_cast<double>(n);
  double sab = 0.0, saa = 0.0, sbb = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return saa > 0.0 && sbb > 0.0 ? sab / std::sqrt(saa * sbb) : 0.0;
}
void append(PriorCalibration& to, const PriorCalibration& c) {
  for (auto [dst, src] : {std::pair{&to.friction_rel, &c.friction_rel},
                          std::pair{&to.friction_z, &c.friction_z}, std::pair{&to.fuel_rel, &c.fuel_rel},
                          std::pair{&to.fuel_z, &c.fuel_z}, std::pair{&to.fused_z, &c.fused_z}})
    dst->insert(dst->end(), src->begin(), src->end());
}
void print_prior_row(const std::string& name, const PriorCalibration& c) {
  constexpr double k1 = 0.6827;  // 1σ of a normal distribution
  std::printf("%-16s %5zu | %6.1f%% %6.2f %6.2f | %6.1f%% %6.2f %6.2f | %6.2f %6.2f | %5.2f\n", name.c_str(),
              c.friction_z.size(), 100.0 * rms_of(c.friction_rel), abs_quantile(c.friction_z, k1),
              100.0 * abs_quantile(c.friction_rel, k1), 100.0 * rms_of(c.fuel_rel),
              abs_quantile(c.fuel_z, k1), 100.0 * abs_quantile(c.fuel_rel, k1), abs_quantile(c.fused_z, k1),
              abs_quantile(c.fused_z, 0.9545), correlation(c.friction_rel, c.fuel_rel));
}

/// 5-95 % interval over engines of the pooled 68th percentiles (friction z68, fuel z68, friction rel68):
/// resampling whole engines, since an engine's errors are mostly one bias (2000 resamples, fixed seed).
void print_prior_bootstrap(const std::string& role, const std::vector<PriorCalibration>& v) {
  constexpr double k1 = 0.6827;
  constexpr int kResamples = 2000;
  if (v.size() < 2) return;
  std::mt19937_64 gen(20261129);
  std::array<std::vector<double>, 3> q;
  for (int b = 0; b < kResamples; ++b) {
    PriorCalibration pool;
    for (std::size_t i = 0; i < v.size(); ++i) append(pool, v[gen() % v.size()]);
    q[0].push_back(abs_quantile(pool.friction_z, k1));
    q[1].push_back(abs_quantile(pool.fuel_z, k1));
    q[2].push_back(100.0 * abs_quantile(pool.friction_rel, k1));
  }
  for (auto& x : q) std::sort(x.begin(), x.end());
  const auto lo = [](const std::vector<double>& x) {
    return x[static_cast<std::size_t>(0.05 * (x.size() - 1))];
  };
  const auto hi = [](const std::vector<double>& x) {
    return x[static_cast<std::size_t>(0.95 * (x.size() - 1))];
  };
  std::printf(
      "%-16s 5-95 %% over %zu engines: friction z68 %.2f-%.2f, rel68 %.1f-%.1f %%; fuel z68 %.2f-%.2f\n",
      role.c_str(), v.size(), lo(q[0]), hi(q[0]), lo(q[2]), hi(q[2]), lo(q[1]), hi(q[1]));
}

}  // namespace

/// --bed-priors: how far the generic priors sit from engines (daemon_bed.hpp PriorCalibration), per engine
/// and pooled over the calibration set (the one that sets the priors' 1σ), the tuning and the report engines.
int run_bed_priors(bool all, const DaemonBedOptions& opt) {
  std::printf(
      "Priors on the map without a load signal, fresh state, cycles whose fused brake rests on the priors "
      "alone.\nfriction (generic correlation) and fuel (fuel model's indicated): RMS of (estimate - truth) / "
      "estimate, z68 = 68th percentile of |error| / claimed 1 sigma (1.00: the 1 sigma is right; 0.8: "
      "20 %% too wide), rel68 = 68th percentile of |relative error| (the relative 1 sigma the engines "
      "support); fused brake: z68 and z95 (2.00 expected); corr: correlation of the two relative errors "
      "(> 0: they partly cancel in the brake torque). Cycles in or next to a fuel cut-off are left out.\n"
      "engine           cycles | fric RMS    z68  rel68 | fuel RMS    z68  rel68 | fused z68  z95 |  corr\n");
  std::vector<std::pair<std::string, const sim::BedEngine*>> engines;
  for (const auto& e : sim::calibration_engines()) engines.emplace_back("calibration", &e);
  if (all)
    for (const auto& e : sim::unseen_engines()) engines.emplace_back(e.report ? "report" : "tuning", &e);
  std::map<std::string, PriorCalibration> pools;
  std::map<std::string, std::vector<PriorCalibration>> per_engine;
  int rc = 0;
  for (const auto& [role, e] : engines) {
    PriorCalibration c;
    std::string err;
    if (!evaluate_prior_calibration_engine(*e, opt, c, err)) {
      std::fprintf(stderr, "error: %s\n", err.c_str());
      rc = 1;
      continue;
    }
    print_prior_row(e->name, c);
    append(pools[role], c);
    per_engine[role].push_back(std::move(c));
    std::fflush(stdout);
  }
  std::printf("pooled:\n");
  for (const char* role : {"calibration", "tuning", "report"})
    if (pools.count(role) != 0) print_prior_row(std::string(role) + " all", pools[role]);
  for (const char* role : {"calibration", "tuning", "report"})
    if (per_engine.count(role) != 0) print_prior_bootstrap(role, per_engine[role]);
  return rc;
}

}  // namespace torqued::eval
