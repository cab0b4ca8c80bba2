#pragma once
// Test helper: a logic-analyzer edge CSV (docs/io.md format) of a 60-2 wheel with one cam pulse per 720°, at
// a constant or linearly ramping speed, from the shared sensor simulator (synthetic_wheel.hpp). Tooth 0 is
// 10° after the capture starts; the cam is high from 100° to 460° after tooth 0. The truth (speed) is exact.
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "synthetic_wheel.hpp"

namespace torqued::test {

struct WheelRun {
  double rpm0 = 3000.0;  ///< speed at t = 0
  double rpm1 = 3000.0;  ///< speed at the end (linear in time)
  double duration_s = 2.0;
};

/// Returns the number of crank rising edges written (-1 when the file cannot be written).
inline int write_edge_csv(const std::string& path, const WheelRun& run) {
  SynthOptions o;
  o.wheel = wheel_nm(60, 2);
  o.rpm0 = run.rpm0;
  o.rpm1 = run.rpm1;
  o.duration_s = run.duration_s;
  o.start_deg = 710.0;  // 10° before tooth 0
  o.cam_rise_deg = 100.0;
  o.cam_fall_deg = 460.0;
  const SynthOutput out = synthesize(o);
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return -1;
  std::fprintf(f, "Time [s],crank,cam\n0.000000000,0,0\n");
  int level[2] = {0, 0};
  for (const EdgeEvent& e : out.edges) {
    level[e.channel] = e.level;
    std::fprintf(f, "%.9f,%d,%d\n", static_cast<double>(e.t_ns) * 1e-9, level[0], level[1]);
  }
  std::fclose(f);
  return static_cast<int>(out.teeth.size());
}

/// Hostile input: replaces the integer part of the time on line `line` (1-based) of a text file with
/// `seconds` ("100000": one flipped digit far ahead of the capture), or adds `shift_s` to every time from
/// that line on when `shift_s` != 0 (a genuine clock jump). Returns false when the file has no such line.
inline bool corrupt_edge_csv_time(const std::string& path, int line, const std::string& seconds,
                                  double shift_s = 0.0) {
  std::ifstream in(path);
  std::string out, l;
  int n = 0;
  bool done = false;
  while (std::getline(in, l)) {
    ++n;
    const auto dot = l.find('.');
    if (n == line && shift_s == 0.0 && dot != std::string::npos) {
      l = seconds + l.substr(dot);
      done = true;
    } else if (n >= line && shift_s != 0.0 && dot != std::string::npos) {
      char buf[48];
      std::snprintf(buf, sizeof buf, "%.9f", std::stod(l.substr(0, l.find(','))) + shift_s);
      l = buf + l.substr(l.find(','));
      done = true;
    }
    out += l + "\n";
  }
  in.close();
  std::ofstream(path, std::ios::trunc) << out;
  return done;
}

}  // namespace torqued::test
