// Views of a SimOutput for estimator tests that bypass io/: ideal tooth samples and decoded CAN signals.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "can_codec.hpp"
#include "engine_sim.hpp"

namespace torqued::sim {

std::vector<ToothSample> ideal_tooth_samples(const SimOutput& out, const Scenario& scenario) {
  const auto nominal = nominal_tooth_angles_rad(scenario.wheel);
  const int teeth = static_cast<int>(nominal.size());
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  std::vector<ToothSample> s;
  s.reserve(out.teeth.size());
  std::int64_t prev_ns = 0;
  for (std::size_t i = 0; i < out.teeth.size(); ++i) {
    const ToothTruth& t = out.teeth[i];
    const int k = t.tooth % teeth;
    const int rev = t.tooth / teeth;
    ToothSample x;
    x.t_ns = t.t_meas_ns;
    x.tooth = t.tooth;
    x.angle_rad = kTwoPi * rev + nominal[static_cast<std::size_t>(k)];
    x.width_rad = k > 0 ? nominal[static_cast<std::size_t>(k)] - nominal[static_cast<std::size_t>(k - 1)]
                        : nominal[0] + kTwoPi - nominal[static_cast<std::size_t>(teeth - 1)];
    x.dt_s = i == 0 ? 0.0 : static_cast<double>(t.t_meas_ns - prev_ns) * 1e-9;
    x.synced = i > 0;
    prev_ns = t.t_meas_ns;
    s.push_back(x);
  }
  return s;
}

EngineSignals signals_at(const SimOutput& out, double t_s, double max_age_s) {
  EngineSignals sig;
  const auto t_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
  const auto max_age_ns = static_cast<std::int64_t>(std::llround(max_age_s * 1e9));
  // First frame after t: walk back until the newest frame of every message was seen (or we are too old).
  auto it = std::upper_bound(out.can.begin(), out.can.end(), t_ns,
                             [](std::int64_t v, const CanFrame& f) { return v < f.t_ns; });
  bool seen1 = false, seen2 = false, seen3 = false, seen4 = false, seen5 = false, seen6 = false;
  while (it != out.can.begin()) {
    --it;
    const CanFrame& f = *it;
    if (t_ns - f.t_ns > max_age_ns) break;
    const MessageDef* m = find_message(f.id);
    if (m == nullptr) continue;
    const auto get = [&](const char* name) { return unpack_signal(*find_signal(*m, name), f.data.data()); };
    sig.t_ns = std::max(sig.t_ns, f.t_ns);
    if (f.id == kEngine1Id && !seen1) {
      seen1 = true;
      sig.map_pa = get("MAP") * 1e3;
      sig.map_valid = true;
      sig.intake_temp_k = get("IntakeAirTemp") + 273.15;
      sig.intake_temp_valid = true;
      sig.throttle_pct = get("Throttle");
      sig.throttle_valid = true;
    } else if (f.id == kEngine2Id && !seen2) {
      seen2 = true;
      sig.maf_kg_s = get("MAF") * 1e-3;
      sig.maf_valid = true;
      sig.fuel_mass_kg = get("FuelMass") * 1e-6;
      sig.fuel_mass_valid = true;
      sig.spark_advance_deg = get("SparkAdvance");
      sig.spark_valid = true;
      sig.lambda = get("Lambda");
      sig.lambda_valid = true;
      sig.fuel_cutoff = get("FuelCutoff") > 0.5;
      sig.fuel_cutoff_valid = true;
    } else if (f.id == kEngine3Id && !seen3) {
      seen3 = true;
      sig.oil_temp_c = get("OilTemp");
      sig.oil_temp_valid = true;
    } else if (f.id == kDyno1Id && !seen4) {
      seen4 = true;
      sig.load_torque_nm = get("LoadTorque");
      sig.load_torque_valid = true;
    } else if (f.id == kEm1Id && !seen5) {
      seen5 = true;
      sig.em_torque_nm = get("EmTorque");
      sig.em_torque_valid = true;
    } else if (f.id == kVeh1Id && !seen6) {
      seen6 =
          true;  // the one clutch flag, as em_sole_load (hybrid) and as neutral (vehicle): the config picks
      sig.em_sole_load = sig.neutral = get("ClutchOpen") > 0.5;
      sig.em_sole_load_valid = sig.neutral_valid = true;
    }
    if (seen1 && seen2 && seen3 && seen4 && seen5 && seen6) break;
  }
  return sig;
}

}  // namespace torqued::sim
