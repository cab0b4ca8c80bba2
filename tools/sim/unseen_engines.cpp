// The unseen-engines test bed (unseen_engines.hpp; docs/simulator.md §7).
#include "unseen_engines.hpp"

#include <array>

#include "sim_random.hpp"

namespace torqued::sim {

namespace {

struct Family {
  int cylinders;
  std::array<int, kMaxCylinders> firing;
  double bore_lo, bore_hi, stroke_lo, stroke_hi, rod_lo, rod_hi;  // m
  double j_lo, j_hi, m_lo, m_hi;                                  // kg m², kg
};

// Spec-sheet ranges of production SI engines (I3 1.0-1.3 L, I4 1.4-2.2 L, I6 2.5-3.0 L).
const Family kI3{3,   {1, 2, 3, 0, 0, 0, 0, 0}, 0.071, 0.078, 0.078, 0.092, 0.125, 0.140, 0.09, 0.14, 0.35,
                 0.50};
const Family kI4{4,   {1, 3, 4, 2, 0, 0, 0, 0}, 0.074, 0.088, 0.080, 0.092, 0.135, 0.150, 0.12, 0.20, 0.42,
                 0.60};
const Family kI6{6,   {1, 5, 3, 6, 2, 4, 0, 0}, 0.080, 0.087, 0.080, 0.090, 0.140, 0.150, 0.16, 0.26, 0.45,
                 0.60};

double draw(SimRandom& r, double lo, double hi) { return lo + (hi - lo) * r.uniform(); }

BedEngine make(const std::string& name, bool report, const Family& f, int wheel_positions,
               std::uint64_t seed) {
  SimRandom r(seed, 11);
  BedEngine e;
  e.name = name;
  e.report = report;
  EngineGeometry& g = e.spec;
  g.cylinders = f.cylinders;
  g.firing_order = f.firing;
  g.bore_m = draw(r, f.bore_lo, f.bore_hi);
  g.stroke_m = draw(r, f.stroke_lo, f.stroke_hi);
  g.rod_m = draw(r, f.rod_lo, f.rod_hi);
  g.compression_ratio = draw(r, 9.5, 12.0);
  g.j_rot_kgm2 = draw(r, f.j_lo, f.j_hi);
  g.m_osc_kg = draw(r, f.m_lo, f.m_hi);

  Scenario& s = e.truth;
  s.name = name;
  s.seed = seed;
  s.engine = g;
  s.engine.j_rot_kgm2 = g.j_rot_kgm2 * (1.0 + draw(r, -0.10, 0.10));  // catalogue inertia ±10 %
  s.engine.m_osc_kg = g.m_osc_kg * (1.0 + draw(r, -0.10, 0.10));
  s.wheel.positions = wheel_positions;
  s.wheel.missing = wheel_positions == 36 ? 1 : 2;
  // Friction: level ±40 % around a generic FMEP curve, shape (constant / linear / quadratic parts) drawn
  // apart.
  const double level = draw(r, 0.6, 1.4);
  s.friction.paper_law = false;
  s.friction.fmep0_kpa = level * draw(r, 75.0, 120.0);
  s.friction.fmep1_kpa = level * draw(r, 5.0, 25.0);
  s.friction.fmep2_kpa = level * draw(r, 2.0, 8.0);
  s.friction.oil_coeff_per_c = draw(r, -6e-3, -2e-3);
  // Combustion phasing and duration, heat loss, gas properties, valve timing, breathing.
  CombustionParams& c = s.combustion;
  c.burn_duration_deg = draw(r, 40.0, 65.0);
  c.wiebe_a = draw(r, 4.0, 6.0);
  c.wiebe_m = draw(r, 1.5, 2.5);
  c.heat_fraction = draw(r, 0.72, 0.85);
  c.gamma = draw(r, 1.28, 1.34);
  c.evo_deg = draw(r, 120.0, 160.0);  // ≥ 130° overlaps the next cylinder's 50-20° BTDC window on an I4
  c.blowdown_end_deg = c.evo_deg + draw(r, 60.0, 80.0);
  c.vol_efficiency = draw(r, 0.80, 0.92);
  c.exhaust_pa = draw(r, 103000.0, 112000.0);
  c.ivc_deg = 540.0 + draw(r, 0.0, 40.0);  // IVC after BDC
  s.spark_offset_deg = draw(r, -6.0, 6.0);
  s.sensors.tooth_error_sd_deg = draw(r, 0.02, 0.10);
  s.intake_temp_c = draw(r, 20.0, 45.0);
  return e;
}

}  // namespace

const std::vector<BedEngine>& unseen_engines() {
  static const std::vector<BedEngine> list = [] {
    std::vector<BedEngine> v;
    v.push_back(make("tune_i4_60", false, kI4, 60, 1401));
    v.push_back(make("tune_i3_36", false, kI3, 36, 1402));
    v.push_back(make("tune_i6_60", false, kI6, 60, 1403));
    v.push_back(make("rep_i4_60", true, kI4, 60, 1411));
    v.push_back(make("rep_i4_36", true, kI4, 36, 1412));
    v.push_back(make("rep_i3_60", true, kI3, 60, 1413));
    v.push_back(make("rep_i3_36", true, kI3, 36, 1414));
    v.push_back(make("rep_i6_60", true, kI6, 60, 1415));
    v.push_back(make("rep_i6_36", true, kI6, 36, 1416));
    return v;
  }();
  return list;
}

const std::vector<BedEngine>& calibration_engines() {
  static const std::vector<BedEngine> list = [] {
    constexpr int kEngines = 12;
    const std::array<std::pair<const Family*, const char*>, 3> families{
        {{&kI4, "i4"}, {&kI3, "i3"}, {&kI6, "i6"}}};
    std::vector<BedEngine> v;
    for (int i = 0; i < kEngines; ++i) {
      const auto& [f, tag] = families[static_cast<std::size_t>(i % 3)];
      const int wheel = (i / 3) % 2 == 0 ? 60 : 36;
      const std::string name =
          "cal_" + std::string(tag) + "_" + std::to_string(wheel) + "_" + std::to_string(i / 6 + 1);
      v.push_back(make(name, false, *f, wheel, 1421 + static_cast<std::uint64_t>(i)));
    }
    return v;
  }();
  return list;
}

Scenario bed_learning_run(const BedEngine& e) {
  Scenario s = e.truth;
  s.name = e.name + "_learn";
  s.duration_s = 12.0;
  s.warmup_s = 1.5;
  s.idle_control = true;
  // Idle (free engine), a dyno-held overrun ramp 3500 -> 1500 rpm in fuel cut-off, then firing plateaus at
  // several speeds and manifold pressures (the references of the fuel model).
  s.load_phases = {{0.0, LoadMode::kTorque}, {2.5, LoadMode::kDynoSpeed}};
  s.load_torque_nm = {{0.0, 0.0}};
  s.speed_rpm = {{0.0, 800.0},  {2.5, 800.0},  {3.2, 3500.0}, {3.6, 3500.0}, {5.1, 1500.0},
                 {6.5, 1500.0}, {7.0, 2500.0}, {9.0, 2500.0}, {9.5, 3500.0}, {12.0, 3500.0}};
  s.map_target_kpa = {{0.0, 20.0},  {2.5, 20.0},  {2.7, 50.0}, {5.2, 50.0},  {5.3, 40.0},
                      {6.0, 40.0},  {6.05, 80.0}, {7.0, 80.0}, {7.05, 45.0}, {8.0, 45.0},
                      {8.05, 90.0}, {9.0, 90.0},  {9.5, 60.0}, {10.5, 60.0}, {10.55, 35.0}};
  s.fuel_cuts = {{3.6, 5.1, 1000.0}};
  return s;
}

Scenario bed_one_point_learning_run(const BedEngine& e) {
  Scenario s = e.truth;
  s.name = e.name + "_learn_one_point";
  s.duration_s = 12.0;
  s.warmup_s = 1.5;
  s.idle_control = true;
  s.load_phases = {{0.0, LoadMode::kTorque}, {2.5, LoadMode::kDynoSpeed}};
  s.load_torque_nm = {{0.0, 0.0}};
  s.speed_rpm = {{0.0, 800.0},  {2.5, 800.0},  {3.2, 3500.0}, {3.6, 3500.0},
                 {5.1, 1500.0}, {5.8, 2500.0}, {12.0, 2500.0}};
  s.map_target_kpa = {{0.0, 20.0}, {2.5, 20.0}, {2.7, 50.0}, {5.2, 50.0}, {5.3, 60.0}};
  s.fuel_cuts = {{3.6, 5.1, 1000.0}};
  return s;
}

Scenario bed_motoring_run(const BedEngine& e) {
  Scenario s = e.truth;
  s.name = e.name + "_motoring";
  s.duration_s = 10.0;
  s.warmup_s = 1.0;
  s.speed_rpm = {{0.0, 1000.0}, {1.0, 1000.0}, {1.5, 1500.0}, {2.5, 1500.0}, {3.0, 2000.0},
                 {4.0, 2000.0}, {4.5, 2500.0}, {5.5, 2500.0}, {6.0, 3000.0}, {7.0, 3000.0},
                 {7.5, 3500.0}, {8.5, 3500.0}, {9.0, 4000.0}};
  s.map_target_kpa = {{0.0, 35.0}};
  s.fuel_cuts = {{-10.0, 100.0, 0.0}};  // never resumes: motored throughout
  return s;
}

Scenario bed_eval_run(const BedEngine& e, bool short_run) {
  Scenario s = e.truth;
  s.name = e.name + (short_run ? "_eval_short" : "_eval");
  s.seed = e.truth.seed;  // the wheel's machining errors come from the seed: keep the same wheel
  s.warmup_s = 0.5;
  if (short_run) {
    s.duration_s = 4.0;
    s.speed_rpm = {{0.0, 2000.0}, {2.0, 2000.0}, {3.0, 3000.0}};
    s.map_target_kpa = {{0.0, 55.0}, {1.5, 55.0}, {1.55, 80.0}};
    return s;
  }
  s.duration_s = 10.0;
  s.speed_rpm = {{0.0, 1500.0}, {1.5, 1500.0}, {2.0, 2000.0}, {4.0, 2000.0},
                 {5.0, 3500.0}, {6.5, 3500.0}, {8.0, 2500.0}, {10.0, 2500.0}};
  s.map_target_kpa = {{0.0, 40.0}, {1.5, 40.0}, {1.7, 60.0},  {3.0, 60.0}, {3.05, 90.0}, {4.0, 90.0},
                      {4.2, 55.0}, {5.5, 55.0}, {5.55, 35.0}, {6.5, 35.0}, {8.0, 35.0},  {8.2, 65.0}};
  s.fuel_cuts = {{6.5, 7.5, 1000.0}};
  return s;
}

Scenario bed_firing_start_run(const BedEngine& e, bool short_run,
                              std::vector<std::pair<double, double>>* steady_s) {
  Scenario s = e.truth;
  s.name = e.name + (short_run ? "_firing_start_short" : "_firing_start");
  s.seed = e.truth.seed;  // the same wheel
  s.warmup_s = 0.5;
  const double len = short_run ? 2.0 : 6.0, ramp = short_run ? 0.3 : 0.5;
  // No two plateaus at the same load (MAP ≥ 5 % apart): nothing compares two speeds at one load.
  constexpr std::array<std::array<double, 2>, 10> kPlateaus{{{1500, 40},
                                                             {2000, 62},
                                                             {2500, 50},
                                                             {3000, 70},
                                                             {1800, 80},
                                                             {2600, 45},
                                                             {2000, 88},
                                                             {3200, 58},
                                                             {1500, 66},
                                                             {2200, 53}}};
  s.speed_rpm.clear();
  s.map_target_kpa.clear();
  if (steady_s) steady_s->clear();
  for (std::size_t i = 0; i < kPlateaus.size(); ++i) {
    const double t0 = len * static_cast<double>(i);
    s.speed_rpm.push_back({t0 + (i > 0 ? ramp : 0.0), kPlateaus[i][0]});
    s.speed_rpm.push_back({t0 + len, kPlateaus[i][0]});
    s.map_target_kpa.push_back({t0 + (i > 0 ? 0.05 : 0.0), kPlateaus[i][1]});
    s.map_target_kpa.push_back({t0 + len, kPlateaus[i][1]});
    if (steady_s && i + 2 >= kPlateaus.size()) steady_s->push_back({t0 + ramp + 0.5 * len / 3.0, t0 + len});
  }
  s.duration_s = len * static_cast<double>(kPlateaus.size());
  return s;
}

Scenario bed_incycle_regimes_run(const BedEngine& e, std::pair<double, double>* transient_s,
                                 std::pair<double, double>* cutoff_s) {
  Scenario s = bed_firing_start_run(e, true);
  s.name = e.name + "_incycle_regimes";
  const double t0 = s.duration_s;  // 20 s: the last plateau (2200 rpm, 53 kPa) ends here
  const Scenario ev = bed_eval_run(e, false);
  for (Breakpoint b : ev.speed_rpm) s.speed_rpm.push_back({t0 + 0.5 + b.t_s, b.value});
  for (Breakpoint b : ev.map_target_kpa) s.map_target_kpa.push_back({t0 + 0.5 + b.t_s, b.value});
  s.fuel_cuts.clear();
  for (FuelCut c : ev.fuel_cuts)
    s.fuel_cuts.push_back({t0 + 0.5 + c.t_start_s, t0 + 0.5 + c.t_end_s, c.resume_rpm});
  s.duration_s = t0 + 0.5 + ev.duration_s;
  if (transient_s) *transient_s = {t0 + 0.5, t0 + 0.5 + 6.5};
  if (cutoff_s) *cutoff_s = {t0 + 0.5 + 6.3, s.duration_s};
  return s;
}

Scenario bed_ramp_start_run(const BedEngine& e, std::pair<double, double>* ramp_s) {
  Scenario s = e.truth;
  s.name = e.name + "_ramp_start";
  s.seed = e.truth.seed;  // the same wheel
  s.duration_s = 16.0;
  s.warmup_s = 1.5;
  s.idle_control = true;
  s.load_phases = {{0.0, LoadMode::kTorque}, {3.0, LoadMode::kDynoSpeed}};
  s.load_torque_nm = {{0.0, 0.0}};
  s.speed_rpm = {{0.0, 800.0},  {3.0, 800.0},  {4.0, 1500.0},  {6.0, 1500.0},  {7.0, 2500.0},
                 {9.0, 2500.0}, {9.4, 3500.0}, {11.0, 3500.0}, {12.0, 2000.0}, {16.0, 2000.0}};
  s.map_target_kpa = {{0.0, 15.0},   {3.0, 15.0},  {3.2, 35.0},  {5.0, 35.0},  {5.02, 70.0},  {6.0, 70.0},
                      {6.2, 50.0},   {8.5, 50.0},  {8.52, 90.0}, {9.0, 90.0},  {9.2, 60.0},   {11.0, 60.0},
                      {11.05, 20.0}, {12.0, 20.0}, {12.2, 45.0}, {14.0, 45.0}, {14.02, 80.0}, {16.0, 80.0}};
  s.fuel_cuts = {{11.1, 11.9, 1100.0}};
  if (ramp_s) *ramp_s = {0.0, 15.0};
  return s;
}

Scenario bed_vehicle_run(const BedEngine& e, bool short_run) {
  Scenario s = e.truth;
  s.name = e.name + (short_run ? "_vehicle_short" : "_vehicle");
  s.warmup_s = 1.0;
  s.idle_control = true;
  s.vehicle.present = true;
  s.load_phases = {{0.0, LoadMode::kTorque}};
  s.load_torque_nm = {{0.0, 0.0}};
  const double k = short_run ? 0.4 : 1.0;  // time scale of the short subset
  const auto at = [k](double t) { return k * t; };
  // Idle in neutral, clutch closes at 3 s: driving plateaus and steps, overrun in gear (fuel cut-off, the
  // vehicle drives the engine down), then neutral with the fuel still cut: a free coast-down to idle.
  s.vehicle.clutch_closed = {
      {0.0, 0.0}, {at(3.0), 0.0}, {at(3.0) + 1e-3, 1.0}, {at(17.0), 1.0}, {at(17.0) + 1e-3, 0.0}};
  s.speed_rpm = {{0.0, 800.0},       {at(3.0), 800.0},   {at(4.0), 1000.0}, {at(5.0), 1000.0},
                 {at(6.0), 2000.0},  {at(8.0), 2000.0},  {at(9.0), 3000.0}, {at(11.0), 3000.0},
                 {at(12.0), 2400.0}, {at(15.0), 1600.0}, {at(17.0), 2000.0}};
  s.map_target_kpa = {{0.0, 20.0},      {at(3.0), 20.0},  {at(3.0) + 1e-3, 35.0}, {at(5.0), 35.0},
                      {at(5.05), 60.0}, {at(8.0), 60.0},  {at(8.05), 92.0},       {at(9.0), 92.0},
                      {at(9.05), 50.0}, {at(11.0), 50.0}, {at(11.05), 25.0}};
  s.fuel_cuts = {{at(12.0), at(15.0), 1000.0}, {at(17.0), 100.0, 1100.0}};
  s.duration_s = at(21.0);
  return s;
}

Scenario bed_hybrid_run(const BedEngine& e, bool short_run, double* t_drive_s) {
  Scenario s = e.truth;
  s.name = e.name + (short_run ? "_hybrid_short" : "_hybrid");
  s.warmup_s = 1.0;
  s.vehicle.present = true;
  s.e_machine.present = true;
  s.e_machine.ratio = 1.0;
  // Charging points: the machine holds speed (dynamometer-like PI), MAP sets the engine's torque.
  const double p = short_run ? 1.5 : 3.5;    // length of each charging point (s)
  const double t0 = 1.5, td = t0 + 3.0 * p;  // motored start, then 3 points; the clutch closes at td
  if (t_drive_s) *t_drive_s = td;
  s.load_phases = {{0.0, LoadMode::kDynoSpeed}};
  s.vehicle.clutch_closed = {{0.0, 0.0}, {td, 0.0}, {td + 1e-3, 1.0}};
  // Driving (clutch closed): machine torque absorbing positive (generation), negative = boost.
  const double k = short_run ? 0.5 : 1.0;
  const auto at = [td, k](double t) { return td + k * t; };
  s.speed_rpm = {{0.0, 1000.0},          {t0, 2500.0},         {t0 + 0.01, 1200.0},        {t0 + p, 1200.0},
                 {t0 + p + 0.3, 1800.0}, {t0 + 2 * p, 1800.0}, {t0 + 2 * p + 0.3, 2500.0}, {td, 2500.0},
                 {at(2.0), 2000.0},      {at(4.0), 2000.0},    {at(5.0), 2800.0},          {at(7.0), 2800.0},
                 {at(9.0), 1500.0},      {at(11.0), 1500.0}};
  s.map_target_kpa = {{0.0, 30.0},           {t0, 30.0},         {t0 + 0.01, 45.0},         {t0 + p, 45.0},
                      {t0 + p + 0.05, 65.0}, {t0 + 2 * p, 65.0}, {t0 + 2 * p + 0.05, 85.0}, {td, 85.0},
                      {at(0.5), 55.0},       {at(2.5), 55.0},    {at(2.55), 90.0},          {at(5.0), 90.0},
                      {at(5.05), 60.0},      {at(7.0), 60.0},    {at(7.05), 25.0},          {at(9.0), 25.0},
                      {at(9.05), 45.0}};
  s.load_torque_nm = {{0.0, 0.0},       {at(2.5), 0.0},  {at(2.55), -25.0}, {at(5.0), -25.0},
                      {at(5.05), 20.0}, {at(7.0), 20.0}, {at(7.05), 0.0}};
  s.fuel_cuts = {{0.0, t0, 0.0}, {at(7.05), at(9.0), 1000.0}};
  s.duration_s = at(11.0);
  return s;
}

const BedEngine* unseen_engine(const std::string& name) {
  for (const auto& e : unseen_engines())
    if (e.name == name) return &e;
  return nullptr;
}

}  // namespace torqued::sim
