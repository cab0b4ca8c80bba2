// Built-in named scenarios (docs/simulator.md §6). Short by default (2-5 s) so tests stay fast.
#include <functional>
#include <stdexcept>
#include <utility>

#include "engine_sim.hpp"

namespace torqued::sim {

namespace {

Scenario base(const std::string& name, std::uint64_t seed) {
  Scenario s;
  s.name = name;
  s.seed = seed;
  s.duration_s = 2.0;
  return s;
}

/// MAP set-point of the low/mid/high load points; "low" rises with speed so that the engine still delivers
/// positive brake torque against the (speed² growing) friction.
double load_map_kpa(int rpm, const std::string& load) {
  if (load == "low") return 38.0 + 5.0 * (rpm / 1000.0 - 1.0);
  if (load == "mid") return 65.0;
  return 95.0;
}

Scenario steady(int rpm, const std::string& load, std::uint64_t seed) {
  Scenario s = base("steady_" + std::to_string(rpm) + "_" + load, seed);
  s.speed_rpm = {{0.0, static_cast<double>(rpm)}};
  s.map_target_kpa = {{0.0, load_map_kpa(rpm, load)}};
  return s;
}

using Factory = std::function<Scenario()>;

std::vector<std::pair<std::string, Factory>> registry() {
  std::vector<std::pair<std::string, Factory>> r;
  std::uint64_t seed = 100;
  for (int rpm : {1000, 2000, 3000, 4000}) {
    for (const char* load : {"low", "mid", "high"}) {
      const std::uint64_t sd = seed++;
      r.emplace_back("steady_" + std::to_string(rpm) + "_" + load,
                     [rpm, load, sd] { return steady(rpm, load, sd); });
    }
  }
  r.emplace_back("throttle_step", [] {
    Scenario s = base("throttle_step", 201);
    s.duration_s = 3.0;
    s.speed_rpm = {{0.0, 2000.0}};
    s.throttle_pct = {{0.0, 12.0}, {1.0, 12.0}, {1.02, 22.0}};
    return s;
  });
  r.emplace_back("load_step", [] {
    Scenario s = base("load_step", 202);
    s.duration_s = 3.0;
    s.load_phases = {{0.0, LoadMode::kTorque}};
    // e-machine torque step against the engine at fixed MAP: the engine settles near 2500 rpm at 85 N m and
    // decelerates towards a new equilibrium after the step (friction is the only speed-dependent restoring
    // term).
    s.speed_rpm = {{0.0, 2500.0}};  // initial speed
    s.load_torque_nm = {{0.0, 85.0}, {1.0, 85.0}, {1.01, 100.0}};
    s.map_target_kpa = {{0.0, 75.0}};
    return s;
  });
  r.emplace_back("imbalance", [] {
    Scenario s = steady(2000, "mid", 203);
    s.name = "imbalance";
    s.fuel_factor = {1.10, 1.0, 1.0, 0.80, 1, 1, 1, 1};
    return s;
  });
  r.emplace_back("misfire", [] {
    Scenario s = base("misfire", 204);
    s.duration_s = 3.5;
    s.speed_rpm = {{0.0, 2000.0}, {1.5, 2000.0}, {2.0, 4000.0}};
    s.map_target_kpa = {{0.0, 70.0}};
    s.misfires = {{5, 1}, {12, 3}, {20, 2}, {50, 4}, {62, 1}, {63, 1}, {75, 2}};
    return s;
  });
  r.emplace_back("fuel_cut", [] {
    Scenario s = base("fuel_cut", 205);
    s.duration_s = 3.5;
    s.speed_rpm = {{0.0, 3000.0}};
    s.throttle_pct = {{0.0, 16.0}, {0.99, 16.0}, {1.0, 0.0}};
    s.load_phases = {{0.0, LoadMode::kDynoSpeed}, {1.0, LoadMode::kTorque}};  // clutch opens: free coast-down
    s.load_torque_nm = {{0.0, 0.0}};
    s.fuel_cuts = {{1.0, 10.0, 1100.0}};
    s.idle_control = true;
    return s;
  });
  r.emplace_back("idle", [] {
    Scenario s = base("idle", 206);
    s.duration_s = 3.0;
    s.warmup_s = 1.5;
    s.speed_rpm = {{0.0, 800.0}};
    s.load_phases = {{0.0, LoadMode::kTorque}};
    s.load_torque_nm = {{0.0, 0.0}};
    s.throttle_pct = {{0.0, 0.0}};
    s.idle_control = true;
    return s;
  });
  r.emplace_back("three_cyl", [] {
    Scenario s = steady(2000, "mid", 207);
    s.name = "three_cyl";
    s.engine.cylinders = 3;
    s.engine.firing_order = {1, 2, 3, 0, 0, 0, 0, 0};
    s.engine.bore_m = 0.0740;
    s.engine.stroke_m = 0.0775;
    s.engine.rod_m = 0.1300;
    s.engine.j_rot_kgm2 = 0.12;
    s.engine.m_osc_kg = 0.45;
    return s;
  });
  r.emplace_back("wheel_36_1", [] {
    Scenario s = steady(2000, "mid", 208);
    s.name = "wheel_36_1";
    s.wheel.positions = 36;
    s.wheel.missing = 1;
    return s;
  });
  r.emplace_back("demo", [] {
    Scenario s = base("demo", 42);
    s.duration_s = 20.0;
    s.warmup_s = 1.5;
    s.idle_control = true;
    s.load_phases = {{0.0, LoadMode::kTorque}, {3.0, LoadMode::kDynoSpeed}};
    s.load_torque_nm = {{0.0, 0.0}};
    s.speed_rpm = {{0.0, 800.0},   {3.0, 800.0},   {4.0, 1500.0},  {6.0, 1500.0},
                   {7.0, 2500.0},  {9.0, 2500.0},  {9.4, 3500.0},  {11.0, 3500.0},
                   {12.0, 2000.0}, {16.0, 2000.0}, {17.0, 3000.0}, {20.0, 3000.0}};
    s.map_target_kpa = {{0.0, 15.0},   {3.0, 15.0},  {3.2, 35.0},   {5.0, 35.0},  {5.02, 70.0},  {6.0, 70.0},
                        {6.2, 50.0},   {8.5, 50.0},  {8.52, 90.0},  {9.0, 90.0},  {9.2, 60.0},   {11.0, 60.0},
                        {11.05, 20.0}, {12.0, 20.0}, {12.2, 45.0},  {14.0, 45.0}, {14.02, 80.0}, {16.0, 80.0},
                        {16.2, 55.0},  {18.5, 55.0}, {18.52, 95.0}, {20.0, 95.0}};
    s.fuel_cuts = {{11.1, 11.9, 1100.0}};
    s.misfires = {{110, 1}, {111, 3}, {150, 4}, {230, 2}, {300, 1}};
    return s;
  });
  return r;
}

}  // namespace

std::vector<std::string> scenario_names() {
  std::vector<std::string> names;
  for (const auto& [name, f] : registry()) names.push_back(name);
  return names;
}

Scenario scenario_by_name(std::string_view name) {
  std::string all;
  for (const auto& [n, f] : registry()) {
    if (n == name) return f();
    all += (all.empty() ? "" : ", ") + n;
  }
  throw std::invalid_argument("unknown scenario '" + std::string(name) + "'; known: " + all);
}

}  // namespace torqued::sim
