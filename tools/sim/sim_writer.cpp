#include "sim_writer.hpp"

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <stdexcept>

#include "can_codec.hpp"

namespace torqued::sim {

namespace {
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

void appendf(std::string& s, const char* fmt, auto... args) {
  char buf[512];
  const int n = std::snprintf(buf, sizeof buf, fmt, args...);
  if (n > 0) s.append(buf, static_cast<std::size_t>(std::min(n, static_cast<int>(sizeof buf) - 1)));
}

/// Non-negative ns as seconds with exactly 9 decimals (integer arithmetic: no rounding differences).
void append_ns(std::string& s, std::int64_t t_ns) {
  appendf(s, "%" PRId64 ".%09" PRId64, t_ns / 1000000000, t_ns % 1000000000);
}
}  // namespace

std::string edges_csv(const SimOutput& out) {
  std::string s;
  s.reserve(out.edges.size() * 20 + 64);
  s += "Time [s],crank,cam\n";
  std::array<int, 2> lv{out.initial_levels[0], out.initial_levels[1]};
  append_ns(s, 0);
  appendf(s, ",%d,%d\n", lv[0], lv[1]);
  for (const auto& e : out.edges) {
    lv[e.channel & 1u] = e.level;
    append_ns(s, e.t_ns);
    appendf(s, ",%d,%d\n", lv[0], lv[1]);
  }
  return s;
}

std::string candump_log(const SimOutput& out) {
  std::string s;
  s.reserve(out.can.size() * 48);
  for (const auto& f : out.can) {
    const std::int64_t us = f.t_ns / 1000;
    appendf(s, "(%" PRId64 ".%06" PRId64 ") can0 %03X#", kCandumpEpochS + us / 1000000, us % 1000000,
            static_cast<unsigned>(f.id));
    for (int i = 0; i < f.len; ++i)
      appendf(s, "%02X", static_cast<unsigned>(f.data[static_cast<std::size_t>(i)]));
    s += '\n';
  }
  return s;
}

std::string truth_tooth_csv(const SimOutput& out, const Scenario& sc) {
  const int n = sc.engine.cylinders;
  std::string s;
  s.reserve(out.teeth.size() * 110 + 256);
  s += "t_s,tooth,angle720_deg,speed_rad_s,t_ind_nm";
  for (int c = 1; c <= n; ++c) appendf(s, ",t_ind_cyl%d_nm", c);
  s += ",t_mass_nm,t_fric_nm,t_load_nm,t_brake_nm\n";
  for (const auto& t : out.teeth) {
    appendf(s, "%.8f,%d,%.4f,%.4f,%.2f", t.t_s, t.tooth, t.angle720_rad * kRadToDeg, t.speed_rad_s,
            t.t_ind_nm);
    for (int c = 0; c < n; ++c) appendf(s, ",%.2f", t.t_ind_cyl_nm[static_cast<std::size_t>(c)]);
    appendf(s, ",%.2f,%.3f,%.3f,%.2f\n", t.t_mass_nm, t.t_fric_nm, t.t_load_nm, t.t_brake_nm);
  }
  return s;
}

std::string truth_cycle_csv(const SimOutput& out, const Scenario& sc) {
  const int n = sc.engine.cylinders;
  std::string s;
  s += "cycle,t_start_s,t_end_s,speed_mean_rpm,t_ind_mean_nm,t_brake_mean_nm,t_fric_mean_nm,t_load_mean_nm";
  for (int c = 1; c <= n; ++c) appendf(s, ",cyl%d_ind_mean_nm", c);
  for (int c = 1; c <= n; ++c) appendf(s, ",misfire%d", c);
  s += ",fuel_cut,t_mass_mean_nm,map_kpa,oil_temp_c";
  for (int c = 1; c <= n; ++c) appendf(s, ",cyl%d_imep_bar", c);
  for (int c = 1; c <= n; ++c) appendf(s, ",cyl%d_peak_bar", c);
  for (int c = 1; c <= n; ++c) appendf(s, ",cyl%d_fuel_mg", c);
  s += '\n';
  for (const auto& y : out.cycles) {
    appendf(s, "%d,%.9f,%.9f,%.3f,%.4f,%.4f,%.4f,%.4f", y.cycle, y.t_start_s, y.t_end_s,
            y.speed_mean_rad_s * 30.0 / std::numbers::pi, y.t_ind_mean_nm, y.t_brake_mean_nm,
            y.t_fric_mean_nm, y.t_load_mean_nm);
    for (int c = 0; c < n; ++c) appendf(s, ",%.4f", y.cyl_ind_mean_nm[static_cast<std::size_t>(c)]);
    for (int c = 0; c < n; ++c) appendf(s, ",%d", y.misfire[static_cast<std::size_t>(c)] ? 1 : 0);
    appendf(s, ",%d,%.4f,%.3f,%.2f", y.fuel_cut ? 1 : 0, y.t_mass_mean_nm, y.map_pa / 1e3, y.oil_temp_c);
    for (int c = 0; c < n; ++c) appendf(s, ",%.4f", y.cyl_imep_pa[static_cast<std::size_t>(c)] / 1e5);
    for (int c = 0; c < n; ++c) appendf(s, ",%.3f", y.cyl_peak_pa[static_cast<std::size_t>(c)] / 1e5);
    for (int c = 0; c < n; ++c) appendf(s, ",%.4f", y.cyl_fuel_kg[static_cast<std::size_t>(c)] * 1e6);
    s += '\n';
  }
  return s;
}

std::string tooth_errors_csv(const SimOutput& out) {
  std::string s = "tooth,error_deg\n";
  for (std::size_t k = 0; k < out.tooth_error_rad.size(); ++k)
    appendf(s, "%zu,%.6f\n", k, out.tooth_error_rad[k] * kRadToDeg);
  return s;
}

std::string engine_yaml(const Scenario& sc) {
  const auto& e = sc.engine;
  const auto& w = sc.wheel;
  std::string s;
  appendf(s,
          "# Engine and wheel of torque-sim scenario '%s' (seed %" PRIu64
          "); paste into the torqued config.\n",
          sc.name.c_str(), sc.seed);
  s += "engine:\n";
  appendf(s, "  cylinders: %d\n", e.cylinders);
  s += "  firing_order: [";
  for (int i = 0; i < e.cylinders; ++i)
    appendf(s, "%s%d", i ? ", " : "", e.firing_order[static_cast<std::size_t>(i)]);
  s += "]\n";
  appendf(s, "  bore_m: %.6g\n  stroke_m: %.6g\n  rod_m: %.6g\n  compression_ratio: %.6g\n", e.bore_m,
          e.stroke_m, e.rod_m, e.compression_ratio);
  appendf(s, "  j_rot_kgm2: %.6g\n  m_osc_kg: %.6g\n  tdc_offset_deg: %.6g\n  crankcase_pressure_pa: %.6g\n",
          e.j_rot_kgm2, e.m_osc_kg, e.tdc_offset_rad * kRadToDeg, e.crankcase_pressure_pa);
  s += "wheel:\n";
  if (w.tooth_count > 0) {
    s += "  tooth_angles_deg: [";
    for (int k = 0; k < w.tooth_count; ++k)
      appendf(s, "%s%.6g", k ? ", " : "", w.tooth_angles_deg[static_cast<std::size_t>(k)]);
    s += "]\n";
  } else {
    appendf(s, "  teeth: %d\n  missing: %d\n", w.positions, w.missing);
  }
  appendf(s, "  edge: %s\n", w.rising_edge ? "rising" : "falling");
  s += "  crank_channel: crank\n  cam_channel: cam\n  cam_edge: rising\n";
  return s;
}

void write_text_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error("cannot open '" + path.string() + "' for writing");
  f.write(text.data(), static_cast<std::streamsize>(text.size()));
  if (!f) throw std::runtime_error("write to '" + path.string() + "' failed");
}

void write_outputs(const SimOutput& out, const Scenario& sc, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create directory '" + dir.string() + "': " + ec.message());
  write_text_file(dir / "edges.csv", edges_csv(out));
  write_text_file(dir / "can.log", candump_log(out));
  write_text_file(dir / "truth_tooth.csv", truth_tooth_csv(out, sc));
  write_text_file(dir / "truth_cycle.csv", truth_cycle_csv(out, sc));
  write_text_file(dir / "engine.yaml", engine_yaml(sc));
  write_text_file(dir / "tooth_errors.csv", tooth_errors_csv(out));
}

std::string torqued_config_yaml(const EngineGeometry& engine, const Scenario& sc, bool load_signal) {
  return torqued_config_yaml(engine, sc, load_signal, sc.vehicle.present && sc.vehicle.flag_on_can);
}

std::string torqued_config_yaml(const EngineGeometry& engine, const Scenario& sc, bool load_signal,
                                bool vehicle_flag) {
  load_signal = load_signal && !sc.vehicle.present;  // a vehicle has no load signal
  vehicle_flag = vehicle_flag && sc.vehicle.present && sc.vehicle.flag_on_can;
  Scenario spec = sc;
  spec.engine = engine;
  std::string s =
      "# torqued configuration of torque-sim recording '" + sc.name + "' (" +
      (load_signal ? "with the load-torque signal: dynamometer" : "no load-torque signal: vehicle") +
      ").\n# Engine section: the spec sheet, not the simulator's hidden truth. Other keys: defaults.\n";
  const std::string eng = engine_yaml(spec);
  s += eng.substr(eng.find('\n') + 1);  // without engine_yaml's own comment line
  s += "inputs:\n  edges: {backend: file, path: edges.csv, format: csv}\n";
  appendf(s, "  can: {backend: file, path: can.log, time_offset_s: -%" PRId64 "}\n", kCandumpEpochS);
  s += "can:\n  dbc: demo.dbc\n  signals:\n";
  s += "    map:           {message: ENGINE_1, signal: MAP, timeout_ms: 100}\n"
       "    intake_temp:   {message: ENGINE_1, signal: IntakeAirTemp, timeout_ms: 100}\n"
       "    throttle:      {message: ENGINE_1, signal: Throttle, timeout_ms: 100}\n"
       "    maf:           {message: ENGINE_2, signal: MAF, timeout_ms: 100}\n"
       "    fuel_mass:     {message: ENGINE_2, signal: FuelMass, timeout_ms: 100}\n"
       "    spark_advance: {message: ENGINE_2, signal: SparkAdvance, timeout_ms: 100}\n"
       "    lambda:        {message: ENGINE_2, signal: Lambda, timeout_ms: 100}\n"
       "    fuel_cutoff:   {message: ENGINE_2, signal: FuelCutoff, timeout_ms: 100}\n"
       "    oil_temp:      {message: ENGINE_3, signal: OilTemp, timeout_ms: 500}\n";
  if (load_signal) s += "    load_torque:   {message: DYNO_1, signal: LoadTorque, timeout_ms: 100}\n";
  // A scenario with a machine: it is the load the simulator applies, so without the dynamometer signal the
  // machine's torque (EM_1) is the known sole load (hybrid input); with it, the machine is left unbound (the
  // dynamometer already measures the same torque).
  // A vehicle (VehicleSim): the clutch flag VEH_1.ClutchOpen says when the machine is the only load (hybrid:
  // em_sole_load) or when the engine is in neutral (no machine: neutral); unmapped when vehicle_flag is
  // false.
  if (sc.e_machine.present && sc.vehicle.present) {
    s += "    em_torque:     {message: EM_1, signal: EmTorque, timeout_ms: 100}\n";
    if (vehicle_flag) s += "    em_sole_load:  {message: VEH_1, signal: ClutchOpen, timeout_ms: 100}\n";
    appendf(s, "  e_machine: {ratio: %.6g, sign: 1, sole_load: false}\n", sc.e_machine.ratio);
  } else if (sc.vehicle.present) {
    if (vehicle_flag) s += "    neutral:       {message: VEH_1, signal: ClutchOpen, timeout_ms: 100}\n";
  } else if (sc.e_machine.present && !load_signal) {
    s += "    em_torque:     {message: EM_1, signal: EmTorque, timeout_ms: 100}\n";
    appendf(s, "  e_machine: {ratio: %.6g, sign: 1, sole_load: true}\n", sc.e_machine.ratio);
  }
  s += "output:\n  record_dir: \"\"\n  state_dir: \"\"\n";
  return s;
}

void write_recording(const SimOutput& out, const Scenario& sc, const EngineGeometry& engine,
                     const std::filesystem::path& dir) {
  write_outputs(out, sc, dir);
  write_text_file(dir / "demo.dbc", demo_dbc_text());
  // A vehicle: torqued.yaml maps the clutch flag (em_sole_load / neutral), torqued_noload.yaml does not.
  write_text_file(dir / "torqued.yaml", torqued_config_yaml(engine, sc, true, true));
  write_text_file(dir / "torqued_noload.yaml", torqued_config_yaml(engine, sc, false, false));
}

}  // namespace torqued::sim
