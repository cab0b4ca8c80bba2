#include "indicated_eso.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
}  // namespace

IndicatedEso::IndicatedEso(const EngineGeometry& engine, const EnergiesParams& params) noexcept
    : engine_(engine), params_(params) {
  // EN-17: ideal Otto efficiency with the polytropic exponent.
  eta_thermo_ = 1.0 - std::pow(engine.compression_ratio, 1.0 - params.polytropic_kappa);
  reset();
}

void IndicatedEso::reset() noexcept {
  z1_ = z2_ = 0.0;
  init_ = false;
  run_s_ = 0.0;
  recent_.fill(0.0);
  recent_n_ = recent_i_ = 0;
  est_ = TorqueEstimate{};
}

double IndicatedEso::model_efficiency(double lambda) const noexcept {
  return eta_thermo_ * std::min(1.0, lambda) * params_.eso_base_efficiency;
}

bool IndicatedEso::update(const EsoInput& in) noexcept {
  if (!in.valid || !std::isfinite(in.ke_j) || !(in.segment_rad > 0.0) || !(in.segment_dt_s > 0.0) ||
      !std::isfinite(in.fuel_kg) || in.fuel_kg < 0.0 || !std::isfinite(in.friction_nm) ||
      !std::isfinite(in.load_nm) || !(in.lambda > 0.0)) {
    init_ = false;
    est_.health = Health::kInvalidInput;
    return false;
  }
  const double q_mass = engine_.cylinders * in.fuel_kg * params_.fuel_lhv_j_kg / kFourPi;  // EN-16/18
  const double e_ff = model_efficiency(in.lambda);
  if (!init_) {
    z1_ = in.ke_j;
    init_ = true;
    est_.t_ns = in.t_ns;
    est_.torque_nm = (e_ff + z2_) * q_mass;
    est_.health = Health::kNotConverged;
    return true;
  }
  // Predict over the segment (EN-20, angle form), then correct with the pole-placed gains (EN-23).
  const double dth = in.segment_rad;
  const double pred = z1_ + dth * ((e_ff + z2_) * q_mass - in.friction_nm - in.load_nm);
  const double p = std::exp(-params_.eso_omega0 * in.segment_dt_s);
  const double err = in.ke_j - z1_;
  const double l1 = 2.0 - 2.0 * p;
  double l2 = 0.0;
  if (q_mass > 1e-9) l2 = (1.0 - p) * (1.0 - p) / (dth * q_mass);
  z1_ = pred + l1 * err;
  z2_ += l2 * err;
  z2_ = std::clamp(z2_, -0.9 * e_ff, 1.0);  // ΔE_ff cannot make the efficiency negative or above 1 + E_ff
  if (!std::isfinite(z1_) || !std::isfinite(z2_)) {
    reset();
    est_.health = Health::kNumerical;
    return false;
  }
  run_s_ += in.segment_dt_s;
  est_.t_ns = in.t_ns;
  const int n = engine_.cylinders;
  recent_[static_cast<std::size_t>(recent_i_)] = (e_ff + z2_) * q_mass;
  recent_i_ = (recent_i_ + 1) % n;
  if (recent_n_ < n) ++recent_n_;
  double sum = 0.0;
  for (int i = 0; i < recent_n_; ++i) sum += recent_[static_cast<std::size_t>(i)];
  est_.torque_nm = sum / recent_n_;
  est_.uncertainty = 0.05 * std::fabs(est_.torque_nm) + 1.0;
  est_.health = run_s_ * params_.eso_omega0 > 4.0 ? Health::kValid : Health::kNotConverged;
  return true;
}

}  // namespace torqued
