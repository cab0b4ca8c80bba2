#include "metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace torqued::eval {

ErrorStats error_stats(const std::vector<double>& t_s, const std::vector<double>& est,
                       const std::vector<double>& truth) {
  ErrorStats s;
  s.n = std::min({t_s.size(), est.size(), truth.size()});
  if (s.n == 0) return s;
  double sum = 0.0, sum2 = 0.0;
  for (std::size_t i = 0; i < s.n; ++i) {
    const double e = est[i] - truth[i];
    sum += e;
    sum2 += e * e;
    s.mae = std::max(s.mae, std::abs(e));
    if (i > 0) {
      const double ep = est[i - 1] - truth[i - 1];
      s.ise += 0.5 * (e * e + ep * ep) * (t_s[i] - t_s[i - 1]);
    }
  }
  const double n = static_cast<double>(s.n);
  s.bias = sum / n;
  s.rms = std::sqrt(sum2 / n);
  s.sd = std::sqrt(std::max(0.0, sum2 / n - s.bias * s.bias));
  return s;
}

double cycle_mean_pct_error(const std::vector<double>& est_means, const std::vector<double>& truth_means) {
  double num = 0.0, den = 0.0;
  const std::size_t n = std::min(est_means.size(), truth_means.size());
  for (std::size_t i = 0; i < n; ++i) {
    num += std::abs(est_means[i] - truth_means[i]);
    den += std::abs(truth_means[i]);
  }
  if (n == 0 || den == 0.0) return std::numeric_limits<double>::quiet_NaN();
  return 100.0 * num / den;
}

std::size_t convergence_index(const std::vector<double>& err, double tol) {
  std::size_t k = err.size();
  while (k > 0 && std::abs(err[k - 1]) <= tol) --k;
  return k;  // err.size() if the last one is outside the tolerance (never converged)
}

double interpolate(const std::vector<double>& x, const std::vector<double>& y, double xq) {
  if (x.empty() || xq < x.front() || xq > x.back()) return std::numeric_limits<double>::quiet_NaN();
  auto it = std::upper_bound(x.begin(), x.end(), xq);
  if (it == x.end()) return y.back();
  const std::size_t j = static_cast<std::size_t>(it - x.begin());
  if (j == 0) return y.front();
  const double x0 = x[j - 1], x1 = x[j];
  const double w = x1 > x0 ? (xq - x0) / (x1 - x0) : 0.0;
  return y[j - 1] + w * (y[j] - y[j - 1]);
}

namespace {

/// Pearson correlation of est with truth shifted by lag (truth evaluated at θ − lag); NaN if too few samples.
double correlation_at(const std::vector<double>& ea, const std::vector<double>& e,
                      const std::vector<double>& ta, const std::vector<double>& tv, double lag) {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < ea.size(); ++i) {
    const double y = interpolate(ta, tv, ea[i] - lag);
    if (!std::isfinite(y) || !std::isfinite(e[i])) continue;
    sx += e[i];
    sy += y;
    sxx += e[i] * e[i];
    syy += y * y;
    sxy += e[i] * y;
    ++n;
  }
  if (n < 8) return std::numeric_limits<double>::quiet_NaN();
  const double dn = static_cast<double>(n);
  const double cov = sxy / dn - sx / dn * sy / dn;
  const double vx = sxx / dn - sx / dn * sx / dn, vy = syy / dn - sy / dn * sy / dn;
  if (vx <= 0 || vy <= 0) return std::numeric_limits<double>::quiet_NaN();
  return cov / std::sqrt(vx * vy);
}

}  // namespace

PhaseLag phase_lag(const std::vector<double>& est_angle_deg, const std::vector<double>& est,
                   const std::vector<double>& truth_angle_deg, const std::vector<double>& truth,
                   double max_lag_deg, double step_deg) {
  PhaseLag out;
  const int steps = static_cast<int>(std::floor(max_lag_deg / step_deg));
  std::vector<double> rho;
  int best = -1;
  for (int k = -steps; k <= steps; ++k) {
    rho.push_back(correlation_at(est_angle_deg, est, truth_angle_deg, truth, k * step_deg));
    const int i = static_cast<int>(rho.size()) - 1;
    if (std::isfinite(rho.back()) && (best < 0 || rho.back() > rho[static_cast<std::size_t>(best)])) best = i;
  }
  if (best < 0) return out;
  out.ok = true;
  out.correlation = rho[static_cast<std::size_t>(best)];
  out.lag_deg = (best - steps) * step_deg;
  if (best > 0 && best + 1 < static_cast<int>(rho.size())) {
    const double a = rho[std::size_t(best - 1)], b = rho[std::size_t(best)], c = rho[std::size_t(best + 1)];
    const double den = a - 2 * b + c;
    if (std::isfinite(a) && std::isfinite(c) && den < 0) out.lag_deg += 0.5 * (a - c) / den * step_deg;
  }
  return out;
}

void count_misfires(const std::vector<bool>& truth, std::uint32_t est_mask, MisfireStats& s) {
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const bool flagged = (est_mask >> k) & 1u;
    ++s.cylinder_cycles;
    if (truth[k]) {
      ++s.true_misfires;
      if (flagged) ++s.detected;
    } else if (flagged) {
      ++s.false_alarms;
    }
  }
}

}  // namespace torqued::eval
