#pragma once
// The tests' shared crank/cam sensor simulator: edge streams with known truth (no engine simulator needed).
// The decoder tests use the edges directly, the chain and service tests write them as an edge CSV
// (synthetic_edge_csv.hpp); the engine simulator in tools/sim is for whole-engine truth.
// The wheel turns with ω(t, θ) = ω_lin(t)·(1 + ripple·sin(order·θ)), integrated with a fine step; tooth edges
// are found by linear interpolation of θ(t). Wheel angle θ is measured like the simulator's: from tooth 0 of
// the revolution in which the cam rises; cycle = 720°.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "engine_geometry.hpp"
#include "records.hpp"

namespace torqued::test {

struct SynthOptions {
  WheelGeometry wheel{};
  double rpm0 = 3000.0, rpm1 = 3000.0;  ///< linear speed ramp over the duration (rpm)
  double duration_s = 0.2;
  double ripple = 0.0;                  ///< relative speed ripple amplitude (-)
  double ripple_order = 2.0;            ///< ripple periods per revolution
  double start_deg = 100.0;             ///< initial wheel angle within 720° (deg)
  std::vector<double> tooth_error_rad;  ///< per tooth of a revolution (true − nominal), empty = none
  bool falling_edges = true;            ///< also emit crank falling edges (half a pitch after each tooth)
  bool cam = true;
  double cam_rise_deg = 45.0, cam_fall_deg = 225.0;
  double step_s = 2e-6;
};

struct SynthTooth {
  std::int64_t t_ns;
  int tooth720;      ///< true index within 720°
  double angle_rad;  ///< true angle within 720° (incl. tooth error)
};

struct SynthOutput {
  std::vector<EdgeEvent> edges;
  std::vector<SynthTooth> teeth;    ///< marking (rising) crank edges only
  std::vector<double> nominal_deg;  ///< nominal tooth angles of one revolution
};

inline SynthOutput synthesize(const SynthOptions& o) {
  SynthOutput out;
  const WheelGeometry& w = o.wheel;
  const int t = w.teeth();
  for (int i = 0; i < t; ++i) {
    out.nominal_deg.push_back(w.tooth_count > 0 ? w.tooth_angles_deg[static_cast<std::size_t>(i)]
                                                : 360.0 * i / w.positions);
  }
  // Event angles within 720° (deg), sorted: crank rise/fall, cam rise/fall.
  struct Ev {
    double deg;
    std::uint8_t ch, level;
    int tooth;
    double err_rad;
  };
  std::vector<Ev> evs;
  const double pitch = 360.0 / w.positions;
  for (int rev = 0; rev < 2; ++rev) {
    for (int i = 0; i < t; ++i) {
      const double err = o.tooth_error_rad.empty() ? 0.0 : o.tooth_error_rad[static_cast<std::size_t>(i)];
      const double a =
          out.nominal_deg[static_cast<std::size_t>(i)] + 360.0 * rev + err * 180.0 / std::numbers::pi;
      evs.push_back({a, 0, 1, rev * t + i, err});
      if (o.falling_edges) evs.push_back({a + 0.5 * pitch, 0, 0, -1, 0.0});
    }
  }
  if (o.cam) {
    evs.push_back({o.cam_rise_deg, 1, 1, -1, 0.0});
    evs.push_back({o.cam_fall_deg, 1, 0, -1, 0.0});
  }
  for (auto& e : evs) e.deg = std::fmod(e.deg + 720.0, 720.0);
  std::sort(evs.begin(), evs.end(), [](const Ev& a, const Ev& b) { return a.deg < b.deg; });

  const double deg_per_rad = 180.0 / std::numbers::pi;
  double theta_deg = o.start_deg;  // unwrapped
  double t_s = 0.0;
  // First event strictly after the start angle.
  long cycle = 0;
  std::size_t k = 0;
  while (k < evs.size() && evs[k].deg <= theta_deg) ++k;
  if (k ==
      evs.size()) {  // the start lies after the cycle's last event: the next one is the first of the next
    k = 0;
    ++cycle;
  }
  auto target = [&](std::size_t kk, long cyc) { return evs[kk].deg + 720.0 * static_cast<double>(cyc); };
  while (t_s < o.duration_s) {
    const double rpm = o.rpm0 + (o.rpm1 - o.rpm0) * t_s / o.duration_s;
    const double omega_deg_s =
        rpm * 6.0 * (1.0 + o.ripple * std::sin(o.ripple_order * theta_deg / deg_per_rad));
    const double next_theta = theta_deg + omega_deg_s * o.step_s;
    while (target(k, cycle) <= next_theta) {
      const double frac = (target(k, cycle) - theta_deg) / (next_theta - theta_deg);
      const double te = t_s + frac * o.step_s;
      const auto t_ns = static_cast<std::int64_t>(std::llround(te * 1e9));
      const Ev& e = evs[k];
      out.edges.push_back(EdgeEvent{t_ns, e.ch, e.level});
      if (e.ch == 0 && e.level == 1) {
        out.teeth.push_back({t_ns, e.tooth, std::fmod(e.deg, 720.0) / deg_per_rad});
      }
      if (++k == evs.size()) {
        k = 0;
        ++cycle;
      }
    }
    theta_deg = next_theta;
    t_s += o.step_s;
  }
  return out;
}

inline WheelGeometry wheel_nm(int n, int m) {
  WheelGeometry w;
  w.positions = n;
  w.missing = m;
  return w;
}

/// Explicit wheel from runs: teeth, missing, teeth, missing, ... on a wheel of `positions` positions;
/// tooth 0 = first tooth after the first gap listed last (i.e. the list starts right after a gap).
inline WheelGeometry wheel_runs(int positions, const std::vector<int>& runs) {
  WheelGeometry w;
  w.positions = positions;
  int pos = 0, n = 0;
  for (std::size_t r = 0; r < runs.size(); ++r) {
    if (r % 2 == 0) {
      for (int i = 0; i < runs[r]; ++i)
        w.tooth_angles_deg[static_cast<std::size_t>(n++)] = 360.0 * (pos++) / positions;
    } else {
      pos += runs[r];
    }
  }
  w.tooth_count = n;
  w.missing = positions - n;
  return w;
}

/// A burst of noise on crank channel 0: 12 pulses of 40 µs at random times within 30 ms of `start_ns`,
/// appended to `edges` (unsorted). Returns the burst's end (ns). The decoder noise tests share it.
inline std::int64_t add_noise_burst(std::vector<EdgeEvent>& edges, std::int64_t start_ns, std::mt19937& rng) {
  const std::int64_t span = 30'000'000, width = 40'000;
  std::uniform_int_distribution<std::int64_t> at(start_ns, start_ns + span);
  for (int k = 0; k < 12; ++k) {
    const std::int64_t t = at(rng);
    edges.push_back(EdgeEvent{t, 0, 1});
    edges.push_back(EdgeEvent{t + width, 0, 0});
  }
  return start_ns + span + width;
}

}  // namespace torqued::test
