// simulate(): the crank-angle integration loop, sensors and truth bookkeeping (docs/simulator.md).
#include "engine_sim.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

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

namespace {

/// One simulate() run: the crank-angle grid, its slow states, the cylinder events, the sensors and the truth
/// bookkeeping. run() steps the grid until the scenario's duration; each step is one method per concern.
class Simulation {
 public:
  Simulation(const Scenario& sc, const std::function<void(double t_s)>& progress);
  SimOutput run();

 private:
  using State = EngineModel::State;
  void init_cylinders();
  void init_edges();
  void init_can();
  [[nodiscard]] double throttle_base(double t, double omega) const;
  /// Every load on the crank (N m); without a vehicle exactly t_load_ (a −0 stays −0 in the truth files).
  [[nodiscard]] double total_load() const {
    return sc_.vehicle.present ? t_load_ + veh_.shaft_nm + veh_.acc_nm : t_load_;
  }
  [[nodiscard]] double edge_angle() const {
    return kFourPi * static_cast<double>(kc_) + tmpl_[ki_].angle_rad;
  }
  void advance_edge();
  CycleAcc& cycle_acc(std::int64_t k);
  void update_fuel_cut(bool rec, double t_rel);
  void cylinder_events(double theta, double oil_c);
  void accumulate_truth(std::int64_t n, bool locked, double t_rel, double theta, double omega, double t_total,
                        double t_mass);
  void cylinder_windows(double theta);
  void step_slow(std::int64_t n, bool locked, double t_rel, double omega);
  [[nodiscard]] double load_command(double t_rel, double dt);
  void emit_can(double t_rel);
  void fill_frame(const MessageDef& m, double t_rel, CanFrame& f);
  void integrate(double theta, const HeldInputs& in, bool rec);
  void record_edge(const EdgeTemplate& et, double the, const HeldInputs& in, bool rec);
  void finish();

  const Scenario& sc_;
  const std::function<void(double t_s)>& progress_;
  SimOutput out_;
  const int ncyl_;
  EngineModel model_;
  AirPath air_;
  SimRandom rng_wheel_, rng_jitter_, rng_can_, rng_noise_;
  std::vector<EdgeTemplate> tmpl_;

  // Integration grid.
  std::int64_t spc_ = 0;  // steps per cycle
  double h_ = 0.0;
  double omega0_ = 0.0;
  static constexpr int kLockCycles = 2;
  std::int64_t n0_ = 0;  // grid index of θ = 0
  double theta_start_ = 0.0;
  [[nodiscard]] double theta_at(std::int64_t n) const { return static_cast<double>(n - n0_) * h_; }

  // Slow states.
  double omega_f_ = 0.0;     // dyno/ECU speed filter (rad/s)
  double dyno_integ_ = 0.0;  // PI integral (N m)
  double t_load_ = 0.0;      // applied load torque (N m): dynamometer, or the machine's (absorbing positive)
  VehicleState veh_{};       // vehicle driveline (clutch, shaft, road load; VehicleSim)
  double idle_integ_ = 0.0;  // idle PI integral (throttle fraction)
  double throttle_ = 0.0;
  double map_s_ = 0.0, maf_s_ = 0.0, load_s_ = 0.0, speed_s_ = 0.0;  // sensor lags
  double last_fuel_mg_ = 0.0, spark_deg_ = 0.0;
  bool fuel_cut_now_ = false;
  std::vector<bool> cut_resumed_;

  // State and cylinder events.
  State y_{};
  std::array<double, kMaxCylinders> next_ivc_{};
  double ivc_psi_ = 0.0;  // IVC relative to the following firing TDC (rad, negative)

  // Edges: template cycle and index of the next edge, levels.
  std::int64_t kc_ = 0;
  std::size_t ki_ = 0;
  std::array<std::uint8_t, 2> level_{};

  // CAN.
  std::vector<MessageDef> msgs_;
  std::vector<std::int64_t> can_k_;
  std::vector<double> can_next_;
  static constexpr std::array<double, 4> kCanOffsets{0.0, 0.0025, 0.005, 0.0075};

  // Truth.
  std::vector<CycleAcc> cyc_;
  std::array<std::int64_t, kMaxCylinders> win_idx_{};
  std::array<double, kMaxCylinders> win_acc_{};
  std::array<bool, kMaxCylinders> win_clean_{};
  double lock_acc_ = 0.0;
  double t_zero_ = 0.0, t_prev_ = 0.0, next_progress_ = 0.5;
  State k1_{}, k2_{}, k3_{}, k4_{}, yt_{}, ye_{};
  ModelEval ev_, ev_e_;
};

void axpy(EngineModel::State& r, const EngineModel::State& a, double s, const EngineModel::State& b) {
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = a[i] + s * b[i];
}

Simulation::Simulation(const Scenario& sc, const std::function<void(double t_s)>& progress)
    : sc_(sc),
      progress_(progress),
      ncyl_(sc.engine.cylinders),
      model_(sc),
      air_(sc.air, sc.combustion, model_.displacement_m3(), sc.intake_temp_c + 273.15),
      rng_wheel_(sc.seed, 1),
      rng_jitter_(sc.seed, 2),
      rng_can_(sc.seed, 3),
      rng_noise_(sc.seed, 4) {
  const int teeth = sc.wheel.teeth();
  out_.tooth_error_rad.resize(static_cast<std::size_t>(teeth));
  for (auto& e : out_.tooth_error_rad) e = rng_wheel_.gaussian(sc.sensors.tooth_error_sd_deg * kDeg);
  tmpl_ = build_template(sc, out_.tooth_error_rad);
  spc_ = static_cast<std::int64_t>(std::llround(720.0 / sc.step_deg));
  h_ = kFourPi / static_cast<double>(spc_);
  omega0_ = std::max(evaluate(sc.speed_rpm, 0.0, 2000.0), 300.0) * kRpm;
  const int free_cycles = static_cast<int>(std::ceil(sc.warmup_s * omega0_ / kFourPi));
  n0_ = static_cast<std::int64_t>(kLockCycles + free_cycles) * spc_;
  theta_start_ = theta_at(0);
  air_.reset(air_.steady_map(throttle_base(0.0, omega0_), omega0_));
  omega_f_ = omega0_;
  veh_.omega_v = omega0_;
  throttle_ = throttle_base(0.0, omega0_);
  map_s_ = air_.map_pa();
  speed_s_ = omega0_;
  cut_resumed_.assign(sc.fuel_cuts.size(), false);
  init_cylinders();
  init_edges();
  init_can();
}

double Simulation::throttle_base(double t, double omega) const {
  if (!sc_.throttle_pct.empty()) return std::clamp(evaluate(sc_.throttle_pct, t, 0.0) / 100.0, 0.0, 1.0);
  if (!sc_.map_target_kpa.empty())
    return air_.throttle_for_map(evaluate(sc_.map_target_kpa, t, 50.0) * 1e3, omega);
  return 0.0;
}

void Simulation::init_cylinders() {
  ivc_psi_ = sc_.combustion.ivc_deg * kDeg - kFourPi;
  const double gamma = sc_.combustion.gamma;
  for (int c = 0; c < ncyl_; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    const double first = model_.tdc_base_rad(c) + ivc_psi_;
    next_ivc_[cu] = first + kFourPi * std::ceil((theta_start_ - first) / kFourPi - 1e-12);
    // A cylinder already between IVC and blowdown end at start-up: motored polytrope from IVC at MAP.
    auto& e = model_.event(c);
    e.theta_tdc_rad = next_ivc_[cu] - kFourPi - ivc_psi_;
    const double psi = theta_start_ - e.theta_tdc_rad;
    e.active = psi <= sc_.combustion.blowdown_end_deg * kDeg;
    e.q_total_j = 0.0;
    e.cycle = -1000000;
    y_[2 + cu] = air_.map_pa() * std::pow(model_.volume_m3(ivc_psi_) / model_.volume_m3(psi), gamma);
  }
  const HeldInputs in{0.0, air_.map_pa(), 90.0, omega0_};
  ModelEval ev;
  State dy;
  model_.derivative(theta_start_, y_, in, dy, &ev);
  y_[1] = 0.5 * ev.inertia_kgm2 * omega0_ * omega0_;
  for (int c = 0; c < ncyl_; ++c)
    win_idx_[static_cast<std::size_t>(c)] = static_cast<std::int64_t>(
        std::floor((theta_start_ - model_.tdc_base_rad(c) + 2.0 * kPi) / kFourPi + 1e-12));
}

void Simulation::init_edges() {
  kc_ = static_cast<std::int64_t>(std::floor(theta_start_ / kFourPi)) - 1;  // template cycle of the next edge
  ki_ = 0;
  while (edge_angle() <= theta_start_) {
    level_[tmpl_[ki_].channel] = tmpl_[ki_].level;
    advance_edge();
  }
}

void Simulation::advance_edge() {
  if (++ki_ == tmpl_.size()) {
    ki_ = 0;
    ++kc_;
  }
}

void Simulation::init_can() {
  // EM_1 only with a machine, VEH_1 only with a vehicle (which has no DYNO_1): without them the frames and
  // their random draws are unchanged.
  for (const MessageDef& m : demo_messages()) {
    if ((m.id == kEm1Id && !sc_.e_machine.present) || (m.id == kDyno1Id && sc_.vehicle.present) ||
        (m.id == kVeh1Id && !(sc_.vehicle.present && sc_.vehicle.flag_on_can)))
      continue;
    msgs_.push_back(m);
  }
  can_k_.assign(msgs_.size(), 0);
  can_next_.resize(msgs_.size());
  for (std::size_t m = 0; m < msgs_.size(); ++m)
    can_next_[m] = std::max(0.0, kCanOffsets[m % 4] + rng_can_.symmetric(sc_.sensors.can_jitter_s));
}

CycleAcc& Simulation::cycle_acc(std::int64_t k) {
  if (static_cast<std::size_t>(k) >= cyc_.size()) cyc_.resize(static_cast<std::size_t>(k) + 1);
  return cyc_[static_cast<std::size_t>(k)];
}

SimOutput Simulation::run() {
  for (std::int64_t n = 0;; ++n) {
    const double theta = theta_at(n);
    const bool locked = n < static_cast<std::int64_t>(kLockCycles) * spc_;
    const bool rec = n >= n0_;
    if (n == n0_) {
      t_zero_ = y_[0];
      out_.initial_levels = level_;
    }
    const double t_rel = rec ? y_[0] - t_zero_ : 0.0;  // schedules are held at t = 0 during warm-up
    if (rec && t_rel >= sc_.duration_s) break;
    if (progress_ && rec && t_rel >= next_progress_) {
      progress_(t_rel);
      next_progress_ += 0.5;
    }
    update_fuel_cut(rec, t_rel);
    spark_deg_ = sc_.spark_advance_deg.empty()
                     ? spark_map_deg(omega_f_ / kRpm, air_.map_pa()) + sc_.spark_offset_deg
                     : evaluate(sc_.spark_advance_deg, t_rel, 15.0);
    const double oil_c = evaluate(sc_.oil_temp_c, t_rel, 90.0);
    cylinder_events(theta, oil_c);

    const double t_total = total_load();
    const HeldInputs in{t_total, air_.map_pa(), oil_c, locked ? omega0_ : 0.0};
    model_.derivative(theta, y_, in, k1_, &ev_);
    const double omega = ev_.omega_rad_s;
    if (!locked && omega < 30.0)
      throw std::runtime_error("scenario '" + sc_.name + "': engine stalled (" +
                               std::to_string(omega / kRpm) + " rpm) at t = " + std::to_string(t_rel) + " s");
    for (int c = 0; c < ncyl_; ++c) {
      auto& e = model_.event(c);
      if (e.active) e.peak_pa = std::max(e.peak_pa, ev_.p_pa[static_cast<std::size_t>(c)]);
    }
    const double alpha =
        (ev_.t_ind_nm - ev_.t_fric_nm - t_total - ev_.half_dinertia * omega * omega) / ev_.inertia_kgm2;
    const double t_mass =
        (ev_.inertia_kgm2 - sc_.engine.j_rot_kgm2) * alpha + ev_.half_dinertia * omega * omega;
    accumulate_truth(n, locked, t_rel, theta, omega, t_total, t_mass);
    cylinder_windows(theta);
    step_slow(n, locked, t_rel, omega);
    if (rec) emit_can(t_rel);
    integrate(theta, in, rec);
  }
  finish();
  return std::move(out_);
}

/// Fuel cut-off state (time intervals, early resume below resume_rpm).
void Simulation::update_fuel_cut(bool rec, double t_rel) {
  fuel_cut_now_ = false;
  for (std::size_t i = 0; i < sc_.fuel_cuts.size(); ++i) {
    const auto& fc = sc_.fuel_cuts[i];
    if (rec && t_rel >= fc.t_start_s && t_rel < fc.t_end_s && !cut_resumed_[i]) {
      if (omega_f_ < fc.resume_rpm * kRpm)
        cut_resumed_[i] = true;
      else
        fuel_cut_now_ = true;
    }
  }
}

/// Cylinder events: the blowdown end closes a cylinder's cycle, IVC starts the closed-cycle integration.
void Simulation::cylinder_events(double theta, double oil_c) {
  const double gamma = sc_.combustion.gamma;
  for (int c = 0; c < ncyl_; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    auto& e = model_.event(c);
    if (e.active && theta - e.theta_tdc_rad > sc_.combustion.blowdown_end_deg * kDeg) {
      e.active = false;
      if (e.cycle >= 0) cycle_acc(e.cycle).truth.cyl_peak_pa[cu] = e.peak_pa;
    }
    if (theta < next_ivc_[cu] - 1e-9) continue;
    const double tdc = next_ivc_[cu] - ivc_psi_;
    next_ivc_[cu] += kFourPi;
    const auto k = static_cast<std::int64_t>(std::floor(tdc / kFourPi + 1e-12));
    bool misfire = false;
    for (const auto& m : sc_.misfires) misfire |= (k >= 0 && m.cycle == k && m.cylinder == c + 1);
    const double fuel = air_.trapped_air_kg(air_.map_pa(), ncyl_) /
                        (sc_.combustion.afr_stoich * sc_.combustion.lambda) * sc_.fuel_factor[cu];
    e.active = true;
    e.theta_tdc_rad = tdc;
    e.q_total_j =
        (misfire || fuel_cut_now_) ? 0.0 : fuel * sc_.combustion.q_lhv_j_kg * sc_.combustion.heat_fraction;
    e.soc_rad = -spark_deg_ * kDeg;
    e.cycle = static_cast<int>(k);
    y_[2 + cu] = air_.map_pa() * std::pow(model_.volume_m3(ivc_psi_) / model_.volume_m3(theta - tdc), gamma);
    e.peak_pa = y_[2 + cu];
    last_fuel_mg_ = fuel_cut_now_ ? 0.0 : fuel * 1e6;
    if (k < 0) continue;
    auto& tr = cycle_acc(k).truth;
    tr.cyl_fuel_kg[cu] = fuel_cut_now_ ? 0.0 : fuel;
    tr.misfire[cu] = misfire;
    tr.fuel_cut = tr.fuel_cut || fuel_cut_now_;
    if (c == sc_.engine.firing_order[0] - 1) {
      tr.map_pa = air_.map_pa();
      tr.oil_temp_c = oil_c;
    }
  }
}

/// Truth accumulators (θ-integrals by the trapezoidal rule on the grid) and the fine trace.
void Simulation::accumulate_truth(std::int64_t n, bool locked, double t_rel, double theta, double omega,
                                  double t_total, double t_mass) {
  if (locked && n >= spc_) lock_acc_ += h_ * (ev_.t_ind_nm - ev_.t_fric_nm);
  if (n < n0_) return;
  const std::int64_t rel = n - n0_;
  const std::int64_t k = rel / spc_;
  const auto add = [&](CycleAcc& a, double w) {
    a.ind += w * ev_.t_ind_nm;
    a.fric += w * ev_.t_fric_nm;
    a.load += w * t_total;
    a.mass += w * t_mass;
  };
  if (rel % spc_ == 0) {
    CycleAcc& a = cycle_acc(k);
    a.started = true;
    a.truth.t_start_s = t_rel;
    add(a, 0.5 * h_);
    if (k > 0) {
      CycleAcc& b = cycle_acc(k - 1);
      add(b, 0.5 * h_);
      b.truth.t_end_s = t_rel;
      b.range_done = b.started;
    }
  } else {
    add(cycle_acc(k), h_);
  }
  if (sc_.trace_every_steps > 0 && rel % sc_.trace_every_steps == 0) {
    FineSample fs;
    fs.t_s = t_rel;
    fs.wheel_angle_rad = theta;
    fs.speed_rad_s = omega;
    fs.kinetic_j = 0.5 * ev_.inertia_kgm2 * omega * omega;
    fs.t_ind_nm = ev_.t_ind_nm;
    fs.t_fric_nm = ev_.t_fric_nm;
    fs.t_load_nm = t_total;
    fs.p_cyl_pa = ev_.p_pa;
    out_.trace.push_back(fs);
  }
}

/// Per-cylinder windows (TDC − 180° .. TDC + 540°): each cylinder's indicated mean and IMEP.
void Simulation::cylinder_windows(double theta) {
  const double v_cyl = model_.displacement_m3() / ncyl_;
  for (int c = 0; c < ncyl_; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    const auto w =
        static_cast<std::int64_t>(std::floor((theta - model_.tdc_base_rad(c) + 2.0 * kPi) / kFourPi + 1e-12));
    if (w != win_idx_[cu]) {
      const double tdc = model_.tdc_base_rad(c) + kFourPi * static_cast<double>(win_idx_[cu]);
      const auto k = static_cast<std::int64_t>(std::floor(tdc / kFourPi + 1e-12));
      if (win_clean_[cu] && k >= 0) {
        CycleAcc& a = cycle_acc(k);
        a.truth.cyl_ind_mean_nm[cu] = win_acc_[cu] / kFourPi;
        a.truth.cyl_imep_pa[cu] = win_acc_[cu] / v_cyl;
        ++a.windows;
      }
      win_idx_[cu] = w;
      win_acc_[cu] = 0.0;
      win_clean_[cu] = true;
    }
    win_acc_[cu] += h_ * ev_.t_cyl_nm[cu];
  }
}

/// Slow dynamics over the time since the previous grid point (explicit Euler, µs steps): load, driveline,
/// idle controller, throttle, air path and the sensors' lags.
void Simulation::step_slow(std::int64_t n, bool locked, double t_rel, double omega) {
  const double dt = n == 0 ? 0.0 : y_[0] - t_prev_;
  t_prev_ = y_[0];
  omega_f_ += dt / sc_.dyno.speed_filter_s * (omega - omega_f_);
  if (locked) {
    if (n == static_cast<std::int64_t>(kLockCycles) * spc_ - 1) {
      // End of the locked start: initialise the load at the measured mean net torque (steady start).
      const double mean_net = lock_acc_ / kFourPi;
      const bool torque_mode = !sc_.load_phases.empty() && sc_.load_phases.front().mode == LoadMode::kTorque;
      t_load_ = torque_mode ? evaluate(sc_.load_torque_nm, 0.0, 0.0) : mean_net;
      dyno_integ_ = t_load_;
    }
  } else {
    const double cmd = load_command(t_rel, dt);
    t_load_ += dt / sc_.dyno.torque_lag_s * (cmd - t_load_);
    if (sc_.vehicle.present) step_vehicle(sc_, veh_, t_rel, dt, omega, omega_f_);
  }
  double u = throttle_base(t_rel, omega_f_);
  if (sc_.idle_control) {
    const double e_rpm = sc_.idle_rpm - omega_f_ / kRpm;
    idle_integ_ = std::clamp(idle_integ_ + sc_.air.idle_ki / 100.0 * e_rpm * dt, 0.0, 0.5);
    u += std::max(0.0, sc_.air.idle_kp / 100.0 * e_rpm + idle_integ_);
  }
  throttle_ = std::clamp(u, 0.0, 1.0);
  air_.step(throttle_, omega, dt);
  const auto lag = [&](double& s, double x, double tau) {
    s += (tau > 0 ? std::min(dt / tau, 1.0) : 1.0) * (x - s);
  };
  lag(map_s_, air_.map_pa(), sc_.sensors.map_lag_s);
  lag(maf_s_, air_.throttle_flow_now_kg_s(), sc_.sensors.maf_lag_s);
  lag(load_s_, t_load_, sc_.sensors.load_lag_s);
  lag(speed_s_, omega, 0.005);
}

/// The dynamometer's (or machine's) torque command: its speed PI, or the scheduled torque (the PI's integral
/// tracking it for a bumpless switch); none on a vehicle without a machine.
double Simulation::load_command(double t_rel, double dt) {
  LoadMode mode = LoadMode::kDynoSpeed;
  for (const auto& ph : sc_.load_phases)
    if (t_rel >= ph.t_start_s) mode = ph.mode;
  if (sc_.vehicle.present && clutch_closed_at(sc_.vehicle, t_rel))
    mode = LoadMode::kTorque;  // the road holds it
  double cmd;
  if (mode == LoadMode::kDynoSpeed) {
    const double e = omega_f_ - evaluate(sc_.speed_rpm, t_rel, 2000.0) * kRpm;
    dyno_integ_ += sc_.dyno.ki_nm_per_rad * e * dt;
    cmd = sc_.dyno.kp_nm_per_rad_s * e + dyno_integ_;
  } else {
    cmd = evaluate(sc_.load_torque_nm, t_rel, 0.0);
    dyno_integ_ = cmd - sc_.dyno.kp_nm_per_rad_s * (omega_f_ - evaluate(sc_.speed_rpm, t_rel, 2000.0) * kRpm);
  }
  if (sc_.vehicle.present && !sc_.e_machine.present) cmd = 0.0;  // no dynamometer, no machine
  return cmd;
}

/// CAN frames due by now (period, jitter and drops per message; µs time stamps like candump).
void Simulation::emit_can(double t_rel) {
  for (std::size_t m = 0; m < msgs_.size(); ++m) {
    while (can_next_[m] <= t_rel) {
      const double ts = can_next_[m];
      ++can_k_[m];
      can_next_[m] = kCanOffsets[m % 4] + static_cast<double>(can_k_[m]) * sc_.sensors.can_period_s +
                     rng_can_.symmetric(sc_.sensors.can_jitter_s);
      if (rng_can_.uniform() < sc_.sensors.can_drop_prob) continue;
      CanFrame f;
      f.t_ns = std::llround(ts * 1e6) * 1000;  // candump resolution: µs
      f.id = msgs_[m].id;
      f.len = static_cast<std::uint8_t>(msgs_[m].dlc);
      fill_frame(msgs_[m], t_rel, f);
      out_.can.push_back(f);
    }
  }
}

void Simulation::fill_frame(const MessageDef& m, double t_rel, CanFrame& f) {
  const auto put = [&](const char* name, double v) { pack_signal(*find_signal(m, name), v, f.data.data()); };
  const SensorParams& s = sc_.sensors;
  const double rpm = speed_s_ / kRpm;
  switch (m.id) {
    case kEngine1Id:
      put("EngineSpeed", rpm + rng_noise_.gaussian(s.speed_noise_rpm));
      put("MAP", (map_s_ + rng_noise_.gaussian(s.map_noise_pa)) / 1e3);
      put("IntakeAirTemp", sc_.intake_temp_c + rng_noise_.gaussian(s.temp_noise_c));
      put("Throttle", throttle_ * 100.0);
      break;
    case kEngine2Id:
      put("MAF", maf_s_ * 1e3 * (1.0 + rng_noise_.gaussian(s.maf_noise_frac)));
      put("FuelMass", last_fuel_mg_);
      put("SparkAdvance", spark_deg_);
      put("Lambda", fuel_cut_now_ ? 5.0 : sc_.combustion.lambda + rng_noise_.gaussian(s.lambda_noise));
      put("FuelCutoff", fuel_cut_now_ ? 1.0 : 0.0);
      break;
    case kEngine3Id:
      put("OilTemp", evaluate(sc_.oil_temp_c, t_rel, 90.0) + rng_noise_.gaussian(s.temp_noise_c));
      put("CoolantTemp", sc_.coolant_temp_c + rng_noise_.gaussian(s.temp_noise_c));
      break;
    case kDyno1Id:
      put("LoadTorque", load_s_ + rng_noise_.gaussian(s.load_noise_nm));
      put("DynoSpeed", rpm + rng_noise_.gaussian(s.speed_noise_rpm));
      break;
    case kVeh1Id:
      put("ClutchOpen", clutch_flag_open(sc_.vehicle, t_rel) ? 1.0 : 0.0);
      break;
    case kEm1Id:
      put("EmTorque", -load_s_ / sc_.e_machine.ratio + rng_noise_.gaussian(sc_.e_machine.noise_nm));
      put("EmSpeed", rpm * sc_.e_machine.ratio);
      break;
    default:
      break;
  }
}

/// RK4 step in crank angle (held slow inputs); the edges inside (θ, θ + h] are placed by partial steps.
void Simulation::integrate(double theta, const HeldInputs& in, bool rec) {
  axpy(yt_, y_, 0.5 * h_, k1_);
  model_.derivative(theta + 0.5 * h_, yt_, in, k2_, nullptr);
  axpy(yt_, y_, 0.5 * h_, k2_);
  model_.derivative(theta + 0.5 * h_, yt_, in, k3_, nullptr);
  axpy(yt_, y_, h_, k3_);
  model_.derivative(theta + h_, yt_, in, k4_, nullptr);
  while (edge_angle() <= theta + h_) {
    const EdgeTemplate& et = tmpl_[ki_];
    const double the = edge_angle();
    const double he = the - theta;
    State q2, q3, q4;
    axpy(yt_, y_, 0.5 * he, k1_);
    model_.derivative(theta + 0.5 * he, yt_, in, q2, nullptr);
    axpy(yt_, y_, 0.5 * he, q2);
    model_.derivative(theta + 0.5 * he, yt_, in, q3, nullptr);
    axpy(yt_, y_, he, q3);
    model_.derivative(the, yt_, in, q4, nullptr);
    for (std::size_t i = 0; i < ye_.size(); ++i)
      ye_[i] = y_[i] + he / 6.0 * (k1_[i] + 2.0 * q2[i] + 2.0 * q3[i] + q4[i]);
    level_[et.channel] = et.level;
    record_edge(et, the, in, rec);
    advance_edge();
  }
  for (std::size_t i = 0; i < y_.size(); ++i)
    y_[i] += h_ / 6.0 * (k1_[i] + 2.0 * k2_[i] + 2.0 * k3_[i] + k4_[i]);
}

/// One edge at wheel angle `the` (state ye_): its measured time (jitter, clock) and, for a marking tooth
/// edge, the per-tooth truth.
void Simulation::record_edge(const EdgeTemplate& et, double the, const HeldInputs& in, bool rec) {
  const double t_true = ye_[0] - t_zero_;
  if (!rec || t_true < 0.0) return;
  double tm = t_true + rng_jitter_.gaussian(sc_.sensors.jitter_sd_s);
  if (sc_.sensors.clock_hz > 0) tm = std::round(tm * sc_.sensors.clock_hz) / sc_.sensors.clock_hz;
  const std::int64_t tns = std::max<std::int64_t>(0, std::llround(tm * 1e9));
  out_.edges.push_back({tns, et.channel, et.level});
  if (et.tooth < 0) return;
  State dy;
  model_.derivative(the, ye_, in, dy, &ev_e_);
  const double w = ev_e_.omega_rad_s;
  const double t_edge_load = total_load();  // after this step's slow update, as the truth always was
  const double acc =
      (ev_e_.t_ind_nm - ev_e_.t_fric_nm - t_edge_load - ev_e_.half_dinertia * w * w) / ev_e_.inertia_kgm2;
  ToothTruth tt;
  tt.t_s = t_true;
  tt.t_meas_ns = tns;
  tt.tooth = et.tooth;
  tt.cycle = static_cast<int>(kc_);
  tt.angle720_rad = et.angle_rad;
  tt.speed_rad_s = w;
  tt.t_ind_nm = ev_e_.t_ind_nm;
  tt.t_ind_cyl_nm = ev_e_.t_cyl_nm;
  tt.t_mass_nm = (ev_e_.inertia_kgm2 - sc_.engine.j_rot_kgm2) * acc + ev_e_.half_dinertia * w * w;
  tt.t_fric_nm = ev_e_.t_fric_nm;
  tt.t_load_nm = t_edge_load;
  tt.t_brake_nm = ev_e_.t_ind_nm - ev_e_.t_fric_nm;
  out_.teeth.push_back(tt);
}

/// The per-cycle truth of every complete cycle; edges and frames in time order.
void Simulation::finish() {
  for (std::size_t k = 0; k < cyc_.size(); ++k) {
    CycleAcc& a = cyc_[k];
    if (!a.range_done || a.windows != ncyl_) continue;
    CycleTruth t = a.truth;
    t.cycle = static_cast<int>(k);
    t.speed_mean_rad_s = kFourPi / (t.t_end_s - t.t_start_s);
    t.t_ind_mean_nm = a.ind / kFourPi;
    t.t_fric_mean_nm = a.fric / kFourPi;
    t.t_load_mean_nm = a.load / kFourPi;
    t.t_mass_mean_nm = a.mass / kFourPi;
    t.t_brake_mean_nm = t.t_ind_mean_nm - t.t_fric_mean_nm;
    out_.cycles.push_back(t);
  }
  std::stable_sort(out_.edges.begin(), out_.edges.end(),
                   [](const EdgeEvent& a, const EdgeEvent& b) { return a.t_ns < b.t_ns; });
  std::stable_sort(out_.can.begin(), out_.can.end(),
                   [](const CanFrame& a, const CanFrame& b) { return a.t_ns < b.t_ns; });
}

}  // namespace

SimOutput simulate(const Scenario& sc, const std::function<void(double t_s)>& progress) {
  validate(sc);
  return Simulation(sc, progress).run();
}

}  // namespace torqued::sim
