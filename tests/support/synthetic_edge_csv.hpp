#pragma once
// Test helper: writes a logic-analyzer edge CSV (docs/io.md "Sources" format) of a 60-2 wheel with a cam edge
// per 720°, at a constant or linearly ramping speed. The analytic truth (speed) is known exactly.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

namespace torqued::test {

struct WheelRun {
  double rpm0 = 3000.0;     ///< speed at t = 0
  double rpm1 = 3000.0;     ///< speed at the end (linear in time)
  double duration_s = 2.0;
};

/// Returns the number of crank rising edges written.
inline int write_edge_csv(const std::string& path, const WheelRun& run) {
  struct Ev { double t; int ch; int level; };
  std::vector<Ev> ev;
  const double w0 = run.rpm0 * 2 * std::numbers::pi / 60, w1 = run.rpm1 * 2 * std::numbers::pi / 60;
  const double a = (w1 - w0) / run.duration_s;  // rad/s^2
  auto time_of = [&](double theta) {  // theta = w0 t + a t^2 / 2
    if (std::abs(a) < 1e-12) return theta / w0;
    return (-w0 + std::sqrt(w0 * w0 + 2 * a * theta)) / a;
  };
  const double deg = std::numbers::pi / 180;
  const double theta_end = w0 * run.duration_s + 0.5 * a * run.duration_s * run.duration_s;
  int rising = 0;
  for (int rev = 0;; ++rev) {
    const double base = rev * 360.0;
    if ((base + 10) * deg > theta_end) break;
    for (int k = 0; k < 58; ++k) {
      const double th = (base + 10.0 + k * 6.0) * deg;  // tooth 0 at 10° of the capture
      if (th + 3 * deg > theta_end) break;
      ev.push_back({time_of(th), 0, 1});
      ev.push_back({time_of(th + 3 * deg), 0, 0});
      ++rising;
    }
    if (rev % 2 == 0) {  // cam: high from 100° to 460° of the 720° cycle
      if ((base + 110) * deg < theta_end) ev.push_back({time_of((base + 110) * deg), 1, 1});
      if ((base + 470) * deg < theta_end) ev.push_back({time_of((base + 470) * deg), 1, 0});
    }
  }
  std::sort(ev.begin(), ev.end(), [](const Ev& x, const Ev& y) { return x.t < y.t; });
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return -1;
  std::fprintf(f, "Time [s],crank,cam\n0.000000000,0,0\n");
  int lv[2] = {0, 0};
  for (const auto& e : ev) {
    lv[e.ch] = e.level;
    std::fprintf(f, "%.9f,%d,%d\n", e.t, lv[0], lv[1]);
  }
  std::fclose(f);
  return rising;
}

}  // namespace torqued::test
