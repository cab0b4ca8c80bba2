// simulate(): the crank-angle integration loop, sensors and truth bookkeeping (docs/simulator.md).
#include "engine_sim.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "air_path.hpp"
#include "can_codec.hpp"
#include "engine_model.hpp"
#include "sim_random.hpp"

namespace torqued::sim {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr double kFourPi = 4.0 * kPi;
constexpr double kRpm = kPi / 30.0;  // rad/s per rpm

/// One edge of the 720° template (wheel angle within the cycle incl. machining error).
struct EdgeTemplate {
  double angle_rad;
  std::uint8_t channel;
  std::uint8_t level;
  int tooth;  ///< tooth index within 720° for marking edges, −1 otherwise
};

/// Vehicle driveline state (VehicleSim): shaft twist, vehicle-side speed referred to the crank, road PI.
struct VehicleState {
  double omega_v = 0.0;   ///< vehicle side, referred to the crank (rad/s)
  double phi = 0.0;       ///< shaft twist (rad)
  double integ = 0.0;     ///< road-load PI integral (N m)
  double shaft_nm = 0.0;  ///< shaft torque on the crank, absorbing positive (N m)
  double acc_nm = 0.0;    ///< accessories (N m)
  bool closed = false;
};

bool clutch_closed_at(const VehicleSim& v, double t) {
  return v.clutch_closed.empty() || evaluate(v.clutch_closed, t, 1.0) > 0.5;
}
/// VEH_1.ClutchOpen: open now and for flag_lead_s either side (drops before closing, rises after opening).
bool clutch_flag_open(const VehicleSim& v, double t) {
  if (v.flag_lag_s > 0.0) return !clutch_closed_at(v, t - v.flag_lag_s);  // a late flag (robustness runs)
  return !clutch_closed_at(v, t) && !clutch_closed_at(v, t - v.flag_lead_s) &&
         !clutch_closed_at(v, t + v.flag_lead_s);
}

/// One explicit-Euler step of the driveline (µs steps; the shaft mode is a few Hz).
void step_vehicle(const Scenario& sc, VehicleState& s, double t_rel, double dt, double omega,
                  double omega_f) {
  const VehicleSim& v = sc.vehicle;
  s.acc_nm = v.accessory_w / std::max(omega_f, 70.0);
  const bool closed = clutch_closed_at(v, t_rel);
  if (closed && !s.closed) {  // synchronised engagement
    s.omega_v = omega;
    s.phi = 0.0;
    s.integ = 0.0;
  }
  s.closed = closed;
  if (!closed) {
    s.shaft_nm = 0.0;
    return;
  }
  const double e = omega_f - evaluate(sc.speed_rpm, t_rel, 2000.0) * std::numbers::pi / 30.0;
  s.integ += v.road_ki * e * dt;
  const double road = v.road_kp * e + s.integ;
  s.shaft_nm = v.stiffness_nm_rad * s.phi + v.damping_nms_rad * (omega - s.omega_v);
  s.omega_v += dt * (s.shaft_nm - road) / v.j_vehicle_kgm2;
  s.phi += dt * (omega - s.omega_v);
}

struct CycleAcc {
  double ind = 0, fric = 0, load = 0, mass = 0;
  bool started = false, range_done = false;
  int windows = 0;
  CycleTruth truth{};
};

void validate(const Scenario& sc) {
  const auto fail = [&](const std::string& what) {
    throw std::invalid_argument("scenario '" + sc.name + "': " + what);
  };
  const int n = sc.engine.cylinders;
  if (n < 1 || n > kMaxCylinders) fail("cylinders must be 1.." + std::to_string(kMaxCylinders));
  std::array<bool, kMaxCylinders> seen{};
  for (int i = 0; i < n; ++i) {
    const int c = sc.engine.firing_order[static_cast<std::size_t>(i)];
    if (c < 1 || c > n || seen[static_cast<std::size_t>(c - 1)])
      fail("firing order is not a permutation of 1..n");
    seen[static_cast<std::size_t>(c - 1)] = true;
  }
  if (sc.engine.bore_m <= 0 || sc.engine.stroke_m <= 0 || sc.engine.rod_m <= sc.engine.crank_radius_m())
    fail("bore/stroke must be > 0 and rod longer than the crank radius");
  if (sc.engine.compression_ratio <= 1.0) fail("compression ratio must be > 1");
  if (sc.engine.j_rot_kgm2 <= 0) fail("j_rot_kgm2 must be > 0");
  const auto& w = sc.wheel;
  if (w.tooth_count == 0 &&
      (w.positions < 3 || w.positions > kMaxTeeth || w.missing < 0 || w.missing >= w.positions - 1))
    fail("wheel needs 3..360 positions and 0 <= missing < positions - 1");
  if (w.tooth_count < 0 || w.tooth_count > kMaxTeeth) fail("tooth_count out of range");
  const double spc = 720.0 / sc.step_deg;
  if (sc.step_deg <= 0 || std::abs(spc - std::round(spc)) > 1e-9) fail("step_deg must divide 720");
  if (!(sc.duration_s > 0)) fail("duration must be > 0");
  if (sc.e_machine.present && !(sc.e_machine.ratio > 0.0)) fail("e-machine ratio must be > 0");
  if (sc.vehicle.present && !(sc.vehicle.j_vehicle_kgm2 > 0.0 && sc.vehicle.stiffness_nm_rad > 0.0))
    fail("vehicle inertia and driveline stiffness must be > 0");
  if (sc.sensors.cam_rise_deg < 0 || sc.sensors.cam_fall_deg <= sc.sensors.cam_rise_deg ||
      sc.sensors.cam_fall_deg >= 720)
    fail("cam window must satisfy 0 <= rise < fall < 720");
  for (const auto& m : sc.misfires)
    if (m.cylinder < 1 || m.cylinder > n) fail("misfire cylinder out of range");
}

std::vector<EdgeTemplate> build_template(const Scenario& sc, const std::vector<double>& err) {
  const auto nominal = nominal_tooth_angles_rad(sc.wheel);
  const int teeth = static_cast<int>(nominal.size());
  double min_gap = 2.0 * kPi;
  for (int k = 0; k < teeth; ++k) {
    const double next = (k + 1 < teeth) ? nominal[static_cast<std::size_t>(k + 1)] : nominal[0] + 2.0 * kPi;
    min_gap = std::min(min_gap, next - nominal[static_cast<std::size_t>(k)]);
  }
  const std::uint8_t mark = sc.wheel.rising_edge ? 1 : 0;
  std::vector<EdgeTemplate> t;
  for (int rev = 0; rev < 2; ++rev) {
    for (int k = 0; k < teeth; ++k) {
      const double a =
          2.0 * kPi * rev + nominal[static_cast<std::size_t>(k)] + err[static_cast<std::size_t>(k)];
      t.push_back({a, 0, mark, k + rev * teeth});
      t.push_back({a + 0.5 * min_gap, 0, static_cast<std::uint8_t>(1 - mark),
                   -1});  // other flank, half a pitch later
    }
  }
  t.push_back({sc.sensors.cam_rise_deg * kDeg, 1, 1, -1});
  t.push_back({sc.sensors.cam_fall_deg * kDeg, 1, 0, -1});
  std::stable_sort(t.begin(), t.end(),
                   [](const EdgeTemplate& a, const EdgeTemplate& b) { return a.angle_rad < b.angle_rad; });
  return t;
}

double spark_map_deg(double rpm, double map_pa) {
  // Simple MBT-like map: more advance at higher speed and lower load.
  return std::clamp(8.0 + 10.0 * (rpm - 800.0) / 3200.0 + 12.0 * (1.0 - map_pa / 100000.0), 4.0, 40.0);
}

}  // namespace

double evaluate(const Schedule& s, double t_s, double fallback) noexcept {
  if (s.empty()) return fallback;
  if (t_s <= s.front().t_s) return s.front().value;
  if (t_s >= s.back().t_s) return s.back().value;
  for (std::size_t i = 1; i < s.size(); ++i) {
    if (t_s < s[i].t_s) {
      const auto& a = s[i - 1];
      const auto& b = s[i];
      const double span = b.t_s - a.t_s;
      return span > 0 ? a.value + (b.value - a.value) * (t_s - a.t_s) / span : b.value;
    }
  }
  return s.back().value;
}

std::vector<double> nominal_tooth_angles_rad(const WheelGeometry& wheel) {
  std::vector<double> a;
  if (wheel.tooth_count > 0) {
    for (int k = 0; k < wheel.tooth_count; ++k)
      a.push_back(wheel.tooth_angles_deg[static_cast<std::size_t>(k)] * kDeg);
  } else {
    for (int k = 0; k < wheel.positions - wheel.missing; ++k) a.push_back(2.0 * kPi * k / wheel.positions);
  }
  return a;
}

SimOutput simulate(const Scenario& sc, const std::function<void(double t_s)>& progress) {
  validate(sc);
  SimOutput out;
  const int ncyl = sc.engine.cylinders;
  EngineModel model(sc);
  const double t_intake_k = sc.intake_temp_c + 273.15;
  AirPath air(sc.air, sc.combustion, model.displacement_m3(), t_intake_k);

  SimRandom rng_wheel(sc.seed, 1), rng_jitter(sc.seed, 2), rng_can(sc.seed, 3), rng_noise(sc.seed, 4);
  const int teeth = sc.wheel.teeth();
  out.tooth_error_rad.resize(static_cast<std::size_t>(teeth));
  for (auto& e : out.tooth_error_rad) e = rng_wheel.gaussian(sc.sensors.tooth_error_sd_deg * kDeg);
  const auto tmpl = build_template(sc, out.tooth_error_rad);

  // --- integration grid -----------------------------------------------------------------------------------
  const auto spc = static_cast<std::int64_t>(std::llround(720.0 / sc.step_deg));  // steps per cycle
  const double h = kFourPi / static_cast<double>(spc);
  const double omega0 = std::max(evaluate(sc.speed_rpm, 0.0, 2000.0), 300.0) * kRpm;
  const int lock_cycles = 2;
  const int free_cycles = static_cast<int>(std::ceil(sc.warmup_s * omega0 / kFourPi));
  const std::int64_t n0 = static_cast<std::int64_t>(lock_cycles + free_cycles) * spc;  // grid index of θ = 0
  const auto theta_at = [&](std::int64_t n) { return static_cast<double>(n - n0) * h; };
  const double theta_start = theta_at(0);

  // --- slow states ----------------------------------------------------------------------------------------
  const auto throttle_base = [&](double t, double omega) {
    if (!sc.throttle_pct.empty()) return std::clamp(evaluate(sc.throttle_pct, t, 0.0) / 100.0, 0.0, 1.0);
    if (!sc.map_target_kpa.empty())
      return air.throttle_for_map(evaluate(sc.map_target_kpa, t, 50.0) * 1e3, omega);
    return 0.0;
  };
  air.reset(air.steady_map(throttle_base(0.0, omega0), omega0));
  double omega_f = omega0;   // dyno/ECU speed filter (rad/s)
  double dyno_integ = 0.0;   // PI integral (N m)
  double t_load = 0.0;       // applied load torque (N m): dynamometer, or the machine's (absorbing positive)
  VehicleState veh{omega0};  // vehicle driveline (clutch, shaft, road load; VehicleSim)
  double idle_integ = 0.0;   // idle PI integral (throttle fraction)
  double throttle = throttle_base(0.0, omega0);
  double map_s = air.map_pa(), maf_s = 0.0, load_s = 0.0, speed_s = omega0;  // sensor lags
  double last_fuel_mg = 0.0, spark_deg = 0.0;
  bool fuel_cut_now = false;
  std::vector<bool> cut_resumed(sc.fuel_cuts.size(), false);

  // --- state and cylinder events --------------------------------------------------------------------------
  EngineModel::State y{};
  std::array<double, kMaxCylinders> next_ivc{};
  const double ivc_rad = sc.combustion.ivc_deg * kDeg;
  const double ivc_psi = ivc_rad - kFourPi;  // IVC relative to the following firing TDC (rad, negative)
  const double gamma = sc.combustion.gamma;
  for (int c = 0; c < ncyl; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    const double first = model.tdc_base_rad(c) + ivc_psi;
    next_ivc[cu] = first + kFourPi * std::ceil((theta_start - first) / kFourPi - 1e-12);
    // A cylinder already between IVC and blowdown end at start-up: motored polytrope from IVC at MAP.
    auto& e = model.event(c);
    e.theta_tdc_rad = next_ivc[cu] - kFourPi - ivc_psi;
    const double psi = theta_start - e.theta_tdc_rad;
    e.active = psi <= sc.combustion.blowdown_end_deg * kDeg;
    e.q_total_j = 0.0;
    e.cycle = -1000000;
    y[2 + cu] = air.map_pa() * std::pow(model.volume_m3(ivc_psi) / model.volume_m3(psi), gamma);
  }
  {
    HeldInputs in{0.0, air.map_pa(), 90.0, omega0};
    ModelEval ev;
    EngineModel::State dy;
    model.derivative(theta_start, y, in, dy, &ev);
    y[1] = 0.5 * ev.inertia_kgm2 * omega0 * omega0;
  }

  // --- edges
  // -------------------------------------------------------------------------------------------------
  auto kc =
      static_cast<std::int64_t>(std::floor(theta_start / kFourPi)) - 1;  // template cycle of the next edge
  std::size_t ki = 0;
  std::array<std::uint8_t, 2> level{};
  const auto edge_angle = [&]() { return kFourPi * static_cast<double>(kc) + tmpl[ki].angle_rad; };
  const auto advance_edge = [&]() {
    if (++ki == tmpl.size()) {
      ki = 0;
      ++kc;
    }
  };
  while (edge_angle() <= theta_start) {
    level[tmpl[ki].channel] = tmpl[ki].level;
    advance_edge();
  }

  // --- CAN
  // --------------------------------------------------------------------------------------------------- EM_1
  // only with a machine, VEH_1 only with a vehicle (which has no DYNO_1): without them the frames and their
  // random draws are unchanged.
  std::vector<MessageDef> msgs;
  for (const MessageDef& m : demo_messages()) {
    if ((m.id == kEm1Id && !sc.e_machine.present) || (m.id == kDyno1Id && sc.vehicle.present) ||
        (m.id == kVeh1Id && !(sc.vehicle.present && sc.vehicle.flag_on_can)))
      continue;
    msgs.push_back(m);
  }
  const double can_offsets[] = {0.0, 0.0025, 0.005, 0.0075};
  std::vector<std::int64_t> can_k(msgs.size(), 0);
  std::vector<double> can_next(msgs.size());
  for (std::size_t m = 0; m < msgs.size(); ++m)
    can_next[m] = std::max(0.0, can_offsets[m % 4] + rng_can.symmetric(sc.sensors.can_jitter_s));

  std::vector<CycleAcc> cyc;
  const auto cycle_acc = [&](std::int64_t k) -> CycleAcc& {
    if (static_cast<std::size_t>(k) >= cyc.size()) cyc.resize(static_cast<std::size_t>(k) + 1);
    return cyc[static_cast<std::size_t>(k)];
  };
  std::array<std::int64_t, kMaxCylinders> win_idx{};
  std::array<double, kMaxCylinders> win_acc{};
  std::array<bool, kMaxCylinders> win_clean{};
  for (int c = 0; c < ncyl; ++c)
    win_idx[static_cast<std::size_t>(c)] = static_cast<std::int64_t>(
        std::floor((theta_start - model.tdc_base_rad(c) + 2.0 * kPi) / kFourPi + 1e-12));

  const double v_cyl = model.displacement_m3() / ncyl;
  double lock_acc = 0.0;
  double t_zero = 0.0, t_prev = 0.0, next_progress = 0.5;
  const int trace_every = sc.trace_every_steps;
  EngineModel::State k1, k2, k3, k4, yt, ye;
  ModelEval ev, ev_e;

  for (std::int64_t n = 0;; ++n) {
    const double theta = theta_at(n);
    const bool locked = n < static_cast<std::int64_t>(lock_cycles) * spc;
    const bool rec = n >= n0;
    if (n == n0) {
      t_zero = y[0];
      out.initial_levels = level;
    }
    const double t_rel = rec ? y[0] - t_zero : 0.0;  // schedules are held at t = 0 during warm-up
    if (rec && t_rel >= sc.duration_s) break;
    if (progress && rec && t_rel >= next_progress) {
      progress(t_rel);
      next_progress += 0.5;
    }

    // Fuel cut-off state (time intervals, early resume below resume_rpm).
    fuel_cut_now = false;
    for (std::size_t i = 0; i < sc.fuel_cuts.size(); ++i) {
      const auto& fc = sc.fuel_cuts[i];
      if (rec && t_rel >= fc.t_start_s && t_rel < fc.t_end_s && !cut_resumed[i]) {
        if (omega_f < fc.resume_rpm * kRpm)
          cut_resumed[i] = true;
        else
          fuel_cut_now = true;
      }
    }
    spark_deg = sc.spark_advance_deg.empty()
                    ? spark_map_deg(omega_f / kRpm, air.map_pa()) + sc.spark_offset_deg
                    : evaluate(sc.spark_advance_deg, t_rel, 15.0);
    const double oil_c = evaluate(sc.oil_temp_c, t_rel, 90.0);

    // Cylinder events: IVC starts the closed-cycle integration.
    for (int c = 0; c < ncyl; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      auto& e = model.event(c);
      if (e.active && theta - e.theta_tdc_rad > sc.combustion.blowdown_end_deg * kDeg) {
        e.active = false;
        if (e.cycle >= 0) cycle_acc(e.cycle).truth.cyl_peak_pa[cu] = e.peak_pa;
      }
      if (theta >= next_ivc[cu] - 1e-9) {
        const double tdc = next_ivc[cu] - ivc_psi;
        next_ivc[cu] += kFourPi;
        const auto k = static_cast<std::int64_t>(std::floor(tdc / kFourPi + 1e-12));
        bool misfire = false;
        for (const auto& m : sc.misfires) misfire |= (k >= 0 && m.cycle == k && m.cylinder == c + 1);
        const double fuel = air.trapped_air_kg(air.map_pa(), ncyl) /
                            (sc.combustion.afr_stoich * sc.combustion.lambda) * sc.fuel_factor[cu];
        e.active = true;
        e.theta_tdc_rad = tdc;
        e.q_total_j =
            (misfire || fuel_cut_now) ? 0.0 : fuel * sc.combustion.q_lhv_j_kg * sc.combustion.heat_fraction;
        e.soc_rad = -spark_deg * kDeg;
        e.cycle = static_cast<int>(k);
        y[2 + cu] = air.map_pa() * std::pow(model.volume_m3(ivc_psi) / model.volume_m3(theta - tdc), gamma);
        e.peak_pa = y[2 + cu];
        last_fuel_mg = fuel_cut_now ? 0.0 : fuel * 1e6;
        if (k >= 0) {
          auto& tr = cycle_acc(k).truth;
          tr.cyl_fuel_kg[cu] = fuel_cut_now ? 0.0 : fuel;
          tr.misfire[cu] = misfire;
          tr.fuel_cut = tr.fuel_cut || fuel_cut_now;
          if (c == sc.engine.firing_order[0] - 1) {
            tr.map_pa = air.map_pa();
            tr.oil_temp_c = oil_c;
          }
        }
      }
    }

    // Every load on the crank (N m); without a vehicle exactly t_load (a −0 stays −0 in the truth files).
    const auto total_load = [&] { return sc.vehicle.present ? t_load + veh.shaft_nm + veh.acc_nm : t_load; };
    const double t_total = total_load();
    const HeldInputs in{t_total, air.map_pa(), oil_c, locked ? omega0 : 0.0};
    model.derivative(theta, y, in, k1, &ev);
    const double omega = ev.omega_rad_s;
    if (!locked && omega < 30.0)
      throw std::runtime_error("scenario '" + sc.name + "': engine stalled (" + std::to_string(omega / kRpm) +
                               " rpm) at t = " + std::to_string(t_rel) + " s");
    for (int c = 0; c < ncyl; ++c) {
      auto& e = model.event(c);
      if (e.active) e.peak_pa = std::max(e.peak_pa, ev.p_pa[static_cast<std::size_t>(c)]);
    }
    const double alpha =
        (ev.t_ind_nm - ev.t_fric_nm - t_total - ev.half_dinertia * omega * omega) / ev.inertia_kgm2;
    const double t_mass = (ev.inertia_kgm2 - sc.engine.j_rot_kgm2) * alpha + ev.half_dinertia * omega * omega;

    // --- truth accumulators (θ-integrals by the trapezoidal rule on the grid) ---
    if (locked && n >= spc) lock_acc += h * (ev.t_ind_nm - ev.t_fric_nm);
    if (rec) {
      const std::int64_t rel = n - n0;
      const std::int64_t k = rel / spc;
      const auto add = [&](CycleAcc& a, double w) {
        a.ind += w * ev.t_ind_nm;
        a.fric += w * ev.t_fric_nm;
        a.load += w * t_total;
        a.mass += w * t_mass;
      };
      if (rel % spc == 0) {
        CycleAcc& a = cycle_acc(k);
        a.started = true;
        a.truth.t_start_s = t_rel;
        add(a, 0.5 * h);
        if (k > 0) {
          CycleAcc& b = cycle_acc(k - 1);
          add(b, 0.5 * h);
          b.truth.t_end_s = t_rel;
          b.range_done = b.started;
        }
      } else {
        add(cycle_acc(k), h);
      }
      if (trace_every > 0 && rel % trace_every == 0) {
        FineSample fs;
        fs.t_s = t_rel;
        fs.wheel_angle_rad = theta;
        fs.speed_rad_s = omega;
        fs.kinetic_j = 0.5 * ev.inertia_kgm2 * omega * omega;
        fs.t_ind_nm = ev.t_ind_nm;
        fs.t_fric_nm = ev.t_fric_nm;
        fs.t_load_nm = t_total;
        fs.p_cyl_pa = ev.p_pa;
        out.trace.push_back(fs);
      }
    }
    for (int c = 0; c < ncyl; ++c) {
      const auto cu = static_cast<std::size_t>(c);
      const auto w = static_cast<std::int64_t>(
          std::floor((theta - model.tdc_base_rad(c) + 2.0 * kPi) / kFourPi + 1e-12));
      if (w != win_idx[cu]) {
        const double tdc = model.tdc_base_rad(c) + kFourPi * static_cast<double>(win_idx[cu]);
        const auto k = static_cast<std::int64_t>(std::floor(tdc / kFourPi + 1e-12));
        if (win_clean[cu] && k >= 0) {
          CycleAcc& a = cycle_acc(k);
          a.truth.cyl_ind_mean_nm[cu] = win_acc[cu] / kFourPi;
          a.truth.cyl_imep_pa[cu] = win_acc[cu] / v_cyl;
          ++a.windows;
        }
        win_idx[cu] = w;
        win_acc[cu] = 0.0;
        win_clean[cu] = true;
      }
      win_acc[cu] += h * ev.t_cyl_nm[cu];
    }

    // --- slow dynamics over the time since the previous grid point (explicit Euler, µs steps) ---
    const double dt = n == 0 ? 0.0 : y[0] - t_prev;
    t_prev = y[0];
    omega_f += dt / sc.dyno.speed_filter_s * (omega - omega_f);
    if (locked) {
      if (n == static_cast<std::int64_t>(lock_cycles) * spc - 1) {
        // End of the locked start: initialise the load at the measured mean net torque (steady start).
        const double mean_net = lock_acc / kFourPi;
        const bool torque_mode = !sc.load_phases.empty() && sc.load_phases.front().mode == LoadMode::kTorque;
        t_load = torque_mode ? evaluate(sc.load_torque_nm, 0.0, 0.0) : mean_net;
        dyno_integ = t_load;
      }
    } else {
      LoadMode mode = LoadMode::kDynoSpeed;
      for (const auto& ph : sc.load_phases)
        if (t_rel >= ph.t_start_s) mode = ph.mode;
      if (sc.vehicle.present && clutch_closed_at(sc.vehicle, t_rel))
        mode = LoadMode::kTorque;  // the road holds it
      double cmd;
      if (mode == LoadMode::kDynoSpeed) {
        const double e = omega_f - evaluate(sc.speed_rpm, t_rel, 2000.0) * kRpm;
        dyno_integ += sc.dyno.ki_nm_per_rad * e * dt;
        cmd = sc.dyno.kp_nm_per_rad_s * e + dyno_integ;
      } else {
        cmd = evaluate(sc.load_torque_nm, t_rel, 0.0);
        dyno_integ = cmd - sc.dyno.kp_nm_per_rad_s * (omega_f - evaluate(sc.speed_rpm, t_rel, 2000.0) * kRpm);
      }
      if (sc.vehicle.present && !sc.e_machine.present) cmd = 0.0;  // no dynamometer, no machine
      t_load += dt / sc.dyno.torque_lag_s * (cmd - t_load);
      if (sc.vehicle.present) step_vehicle(sc, veh, t_rel, dt, omega, omega_f);
    }
    double u = throttle_base(t_rel, omega_f);
    if (sc.idle_control) {
      const double e_rpm = sc.idle_rpm - omega_f / kRpm;
      idle_integ = std::clamp(idle_integ + sc.air.idle_ki / 100.0 * e_rpm * dt, 0.0, 0.5);
      u += std::max(0.0, sc.air.idle_kp / 100.0 * e_rpm + idle_integ);
    }
    throttle = std::clamp(u, 0.0, 1.0);
    air.step(throttle, omega, dt);
    const auto lag = [&](double& s, double x, double tau) {
      s += (tau > 0 ? std::min(dt / tau, 1.0) : 1.0) * (x - s);
    };
    lag(map_s, air.map_pa(), sc.sensors.map_lag_s);
    lag(maf_s, air.throttle_flow_now_kg_s(), sc.sensors.maf_lag_s);
    lag(load_s, t_load, sc.sensors.load_lag_s);
    lag(speed_s, omega, 0.005);

    // --- CAN frames due by now ---
    if (rec) {
      for (std::size_t m = 0; m < msgs.size(); ++m) {
        while (can_next[m] <= t_rel) {
          const double ts = can_next[m];
          ++can_k[m];
          can_next[m] = can_offsets[m % 4] + static_cast<double>(can_k[m]) * sc.sensors.can_period_s +
                        rng_can.symmetric(sc.sensors.can_jitter_s);
          if (rng_can.uniform() < sc.sensors.can_drop_prob) continue;
          CanFrame f;
          f.t_ns = std::llround(ts * 1e6) * 1000;  // candump resolution: µs
          f.id = msgs[m].id;
          f.len = static_cast<std::uint8_t>(msgs[m].dlc);
          const auto put = [&](const char* name, double v) {
            pack_signal(*find_signal(msgs[m], name), v, f.data.data());
          };
          const double rpm = speed_s / kRpm;
          switch (msgs[m].id) {
            case kEngine1Id:
              put("EngineSpeed", rpm + rng_noise.gaussian(sc.sensors.speed_noise_rpm));
              put("MAP", (map_s + rng_noise.gaussian(sc.sensors.map_noise_pa)) / 1e3);
              put("IntakeAirTemp", sc.intake_temp_c + rng_noise.gaussian(sc.sensors.temp_noise_c));
              put("Throttle", throttle * 100.0);
              break;
            case kEngine2Id:
              put("MAF", maf_s * 1e3 * (1.0 + rng_noise.gaussian(sc.sensors.maf_noise_frac)));
              put("FuelMass", last_fuel_mg);
              put("SparkAdvance", spark_deg);
              put("Lambda",
                  fuel_cut_now ? 5.0 : sc.combustion.lambda + rng_noise.gaussian(sc.sensors.lambda_noise));
              put("FuelCutoff", fuel_cut_now ? 1.0 : 0.0);
              break;
            case kEngine3Id:
              put("OilTemp", oil_c + rng_noise.gaussian(sc.sensors.temp_noise_c));
              put("CoolantTemp", sc.coolant_temp_c + rng_noise.gaussian(sc.sensors.temp_noise_c));
              break;
            case kDyno1Id:
              put("LoadTorque", load_s + rng_noise.gaussian(sc.sensors.load_noise_nm));
              put("DynoSpeed", rpm + rng_noise.gaussian(sc.sensors.speed_noise_rpm));
              break;
            case kVeh1Id:
              put("ClutchOpen", clutch_flag_open(sc.vehicle, t_rel) ? 1.0 : 0.0);
              break;
            case kEm1Id:
              put("EmTorque", -load_s / sc.e_machine.ratio + rng_noise.gaussian(sc.e_machine.noise_nm));
              put("EmSpeed", rpm * sc.e_machine.ratio);
              break;
            default:
              break;
          }
          out.can.push_back(f);
        }
      }
    }

    // --- RK4 step in crank angle (held slow inputs) ---
    const auto axpy = [](EngineModel::State& r, const EngineModel::State& a, double s,
                         const EngineModel::State& b) {
      for (std::size_t i = 0; i < r.size(); ++i) r[i] = a[i] + s * b[i];
    };
    axpy(yt, y, 0.5 * h, k1);
    model.derivative(theta + 0.5 * h, yt, in, k2, nullptr);
    axpy(yt, y, 0.5 * h, k2);
    model.derivative(theta + 0.5 * h, yt, in, k3, nullptr);
    axpy(yt, y, h, k3);
    model.derivative(theta + h, yt, in, k4, nullptr);

    // --- edges inside (θ, θ + h]: a partial RK4 step from θ gives the state at the edge angle ---
    while (edge_angle() <= theta + h) {
      const EdgeTemplate& et = tmpl[ki];
      const double the = edge_angle();
      const double he = the - theta;
      EngineModel::State q2, q3, q4;
      axpy(yt, y, 0.5 * he, k1);
      model.derivative(theta + 0.5 * he, yt, in, q2, nullptr);
      axpy(yt, y, 0.5 * he, q2);
      model.derivative(theta + 0.5 * he, yt, in, q3, nullptr);
      axpy(yt, y, he, q3);
      model.derivative(the, yt, in, q4, nullptr);
      for (std::size_t i = 0; i < ye.size(); ++i)
        ye[i] = y[i] + he / 6.0 * (k1[i] + 2.0 * q2[i] + 2.0 * q3[i] + q4[i]);
      level[et.channel] = et.level;
      const double t_true = ye[0] - t_zero;
      if (rec && t_true >= 0.0) {
        double tm = t_true + rng_jitter.gaussian(sc.sensors.jitter_sd_s);
        if (sc.sensors.clock_hz > 0) tm = std::round(tm * sc.sensors.clock_hz) / sc.sensors.clock_hz;
        const std::int64_t tns = std::max<std::int64_t>(0, std::llround(tm * 1e9));
        out.edges.push_back({tns, et.channel, et.level});
        if (et.tooth >= 0) {
          model.derivative(the, ye, in, q2, &ev_e);
          const double w = ev_e.omega_rad_s;
          const double t_edge_load = total_load();  // after this step's slow update, as the truth always was
          const double acc =
              (ev_e.t_ind_nm - ev_e.t_fric_nm - t_edge_load - ev_e.half_dinertia * w * w) / ev_e.inertia_kgm2;
          ToothTruth tt;
          tt.t_s = t_true;
          tt.t_meas_ns = tns;
          tt.tooth = et.tooth;
          tt.cycle = static_cast<int>(kc);
          tt.angle720_rad = et.angle_rad;
          tt.speed_rad_s = w;
          tt.t_ind_nm = ev_e.t_ind_nm;
          tt.t_ind_cyl_nm = ev_e.t_cyl_nm;
          tt.t_mass_nm = (ev_e.inertia_kgm2 - sc.engine.j_rot_kgm2) * acc + ev_e.half_dinertia * w * w;
          tt.t_fric_nm = ev_e.t_fric_nm;
          tt.t_load_nm = t_edge_load;
          tt.t_brake_nm = ev_e.t_ind_nm - ev_e.t_fric_nm;
          out.teeth.push_back(tt);
        }
      }
      advance_edge();
    }
    for (std::size_t i = 0; i < y.size(); ++i) y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
  }

  for (std::size_t k = 0; k < cyc.size(); ++k) {
    CycleAcc& a = cyc[k];
    if (!a.range_done || a.windows != ncyl) continue;
    CycleTruth t = a.truth;
    t.cycle = static_cast<int>(k);
    t.speed_mean_rad_s = kFourPi / (t.t_end_s - t.t_start_s);
    t.t_ind_mean_nm = a.ind / kFourPi;
    t.t_fric_mean_nm = a.fric / kFourPi;
    t.t_load_mean_nm = a.load / kFourPi;
    t.t_mass_mean_nm = a.mass / kFourPi;
    t.t_brake_mean_nm = t.t_ind_mean_nm - t.t_fric_mean_nm;
    out.cycles.push_back(t);
  }
  std::stable_sort(out.edges.begin(), out.edges.end(),
                   [](const EdgeEvent& a, const EdgeEvent& b) { return a.t_ns < b.t_ns; });
  std::stable_sort(out.can.begin(), out.can.end(),
                   [](const CanFrame& a, const CanFrame& b) { return a.t_ns < b.t_ns; });
  return out;
}

}  // namespace torqued::sim
