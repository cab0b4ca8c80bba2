#include "fuel_torque.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace torqued {

namespace {
constexpr double kFourPi = 4.0 * std::numbers::pi;
constexpr int kN = kFuelParams;
Health worst_health(Health a, Health b) noexcept {
  return static_cast<std::uint8_t>(a) > static_cast<std::uint8_t>(b) ? a : b;
}
constexpr std::size_t ix(int i, int j) noexcept { return static_cast<std::size_t>(kN * i + j); }
}  // namespace

FuelTorque::FuelTorque(const EngineGeometry& engine, const FuelTorqueParams& params) noexcept
    : params_(params),
      n_cyl_(engine.cylinders),
      vd_4pi_(std::numbers::pi * 0.25 * engine.bore_m * engine.bore_m * engine.stroke_m * engine.cylinders /
              kFourPi),
      eta_otto_(1.0 - std::pow(std::max(engine.compression_ratio, 1.0), 1.0 - params.kappa)) {
  prior_sd_ = {params_.c0_prior_sd, params_.c1_prior_sd, params_.p_off_prior_sd_pa, params_.k_bp_prior_sd_pa};
  reset();
}

FuelTorqueState FuelTorque::prior_state() const noexcept {
  FuelTorqueState s;
  s.theta = {params_.c0_prior, params_.c1_prior, params_.p_off_prior_pa, params_.k_bp_prior_pa};
  for (int i = 0; i < kN; ++i)
    s.p[ix(i, i)] = prior_sd_[static_cast<std::size_t>(i)] * prior_sd_[static_cast<std::size_t>(i)];
  s.resid_var = params_.residual_sd_nm * params_.residual_sd_nm;
  return s;
}

void FuelTorque::reset() noexcept {
  st_ = prior_state();
  refresh_legacy();
}

int FuelTorque::cell_of(double rpm, double map_pa) noexcept {
  const int si = rpm < 1500.0 ? 0 : rpm < 2500.0 ? 1 : rpm < 3500.0 ? 2 : 3;
  const int mi = map_pa < 40000.0 ? 0 : map_pa < 60000.0 ? 1 : map_pa < 80000.0 ? 2 : 3;
  return si * kFuelCellsMap + mi;
}

std::uint16_t FuelTorque::learned_cells() const noexcept {
  std::uint16_t m = 0;
  for (int i = 0; i < kFuelCells; ++i)
    if (st_.cells[static_cast<std::size_t>(i)] >= params_.cell_min_references)
      m = static_cast<std::uint16_t>(m | (1u << i));
  return m;
}

// EN-16/17 with the pumping loop (fuel_torque.hpp): T_ind = φ·θ − offset.
FuelTorque::Regressor FuelTorque::regressor(const FuelPoint& x) const noexcept {
  const FuelTorqueParams& q = params_;
  const double rpm = std::max(x.rpm, 100.0);
  const double map = std::max(x.map_pa, 5000.0);
  double eta_sp = 1.0;
  if (x.spark_valid) {
    const double mbt = q.mbt_deg + q.mbt_per_krpm_deg * (rpm - q.ref_rpm) * 1e-3 +
                       q.mbt_per_vacuum_deg * (1.0 - std::min(map / q.ref_map_pa, 1.0));
    const double d = x.spark_deg - mbt;
    eta_sp = std::max(0.5, 1.0 - q.spark_k_per_deg2 * d * d);
  }
  const double eta_lam = x.lambda_valid && x.lambda > 0.0 ? std::min(1.0, x.lambda) : 1.0;
  const double g =
      eta_otto_ * eta_sp * eta_lam * n_cyl_ * std::max(x.fuel_kg, 0.0) * q.fuel_lhv_j_kg / kFourPi;
  const double h =
      std::pow(q.ref_rpm / rpm, q.heat_speed_exp) * std::pow(q.ref_map_pa / map, q.heat_load_exp);
  const double flow = rpm / q.rated_rpm * map / q.ref_map_pa;
  Regressor r;
  r.phi = {g, -g * h, -vd_4pi_, -flow * flow * vd_4pi_};
  r.offset = (q.ambient_pa - x.map_pa) * vd_4pi_;
  r.gross_nm = g * (q.c0_prior - q.c1_prior * h);
  return r;
}

double FuelTorque::param_var(const Regressor& r) const noexcept {
  double v = 0.0;
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j)
      v += r.phi[static_cast<std::size_t>(i)] * st_.p[ix(i, j)] * r.phi[static_cast<std::size_t>(j)];
  return std::max(0.0, v);
}

double FuelTorque::residual_var(const Regressor& r) const noexcept {
  // Measured residual scale once learned (68th percentile), else the residual variance seen so far; and the
  // model-form error (what no parameter value removes: the references measure it at their points only).
  const double meas = st_.cover.sd > 0.0 ? st_.cover.sd * st_.cover.sd : st_.resid_var;
  const double form = params_.model_rel_sd * r.gross_nm;
  return meas + form * form;
}

TorqueEstimate FuelTorque::estimate(std::int64_t t_ns, const FuelPoint& x) const noexcept {
  TorqueEstimate e;
  e.t_ns = t_ns;
  if (!std::isfinite(x.fuel_kg) || !std::isfinite(x.map_pa) || !std::isfinite(x.rpm) ||
      (x.spark_valid && !std::isfinite(x.spark_deg)) || (x.lambda_valid && !std::isfinite(x.lambda))) {
    e.health = Health::kInvalidInput;
    return e;
  }
  const Regressor r = regressor(x);
  double t = -r.offset;
  for (int i = 0; i < kN; ++i)
    t += r.phi[static_cast<std::size_t>(i)] * st_.theta[static_cast<std::size_t>(i)];
  e.torque_nm = t;
  // A cell with references measured part of the model-form error (the cell spans 1000 rpm × 20 kPa: part).
  Regressor rv = r;
  if ((learned_cells() >> cell_of(x.rpm, x.map_pa)) & 1u)
    rv.gross_nm *= params_.model_rel_sd > 0.0 ? params_.model_rel_sd_learned / params_.model_rel_sd : 0.0;
  e.uncertainty = std::sqrt(residual_var(rv) + param_var(r));
  e.health = Health::kValid;
  return e;
}

TorqueEstimate FuelTorque::estimate(std::int64_t t_ns, double fuel_kg, double map_pa,
                                    double rpm) const noexcept {
  FuelPoint x;
  x.fuel_kg = fuel_kg;
  x.map_pa = map_pa;
  x.rpm = rpm;
  return estimate(t_ns, x);
}

TorqueEstimate FuelTorque::estimate_window(std::int64_t t_ns, const FuelWindow& w, const FuelPoint& x,
                                           const TorqueEstimate& motored) const noexcept {
  const int n = w.fired + w.cut;
  if (!w.valid || n <= 0) {
    TorqueEstimate e;
    e.t_ns = t_ns;
    e.health = Health::kStaleInput;
    return e;
  }
  const double frac = static_cast<double>(w.fired) / n;
  FuelPoint xf = x;
  xf.fuel_kg = w.fired > 0 ? w.fuel_kg : 0.0;
  xf.map_pa = w.map_fired_pa;
  FuelPoint xc = x;
  xc.fuel_kg = 0.0;
  xc.map_pa = w.map_cut_pa;
  const TorqueEstimate fired = estimate(t_ns, xf);
  const TorqueEstimate cut = motored.health == Health::kValid ? motored : estimate(t_ns, xc);
  TorqueEstimate e = w.fired > 0 ? fired : cut;
  e.torque_nm = frac * fired.torque_nm + (1.0 - frac) * cut.torque_nm;
  const double sd = frac * fired.uncertainty + (1.0 - frac) * cut.uncertainty;
  double tr = transient_sd_nm(w, x);
  if (w.fired > 0 && w.cut > 0)
    tr += params_.transient_sd_scale * std::fabs(fired.torque_nm - cut.torque_nm) / n;
  e.uncertainty = std::hypot(sd, tr);
  if (w.fired > 0 && w.cut > 0) e.health = worst_health(fired.health, cut.health);
  return e;
}

double FuelTorque::transient_sd_nm(const FuelWindow& w, const FuelPoint& x) const noexcept {
  // Spread of one event's share (1/n of the window) of the model torque across the window: fuel and MAP
  // changing. Near the window's edges an event's work is partly its neighbour's.
  const int n = w.fired + w.cut;
  if (n <= 0) return 0.0;
  FuelPoint xf = x;
  xf.fuel_kg = w.fired > 0 ? w.fuel_kg : 0.0;
  xf.map_pa = w.map_fired_pa;
  const Regressor r = regressor(xf);
  const double gross = r.phi[0] * st_.theta[0] + r.phi[1] * st_.theta[1];
  const double per_kg = xf.fuel_kg > 0.0 ? gross / xf.fuel_kg : 0.0;
  const double spread =
      std::fabs(per_kg) * (w.fuel_max_kg - w.fuel_min_kg) + vd_4pi_ * (w.map_max_pa - w.map_min_pa);
  return params_.transient_sd_scale * spread / n;
}

bool FuelTorque::learn(double fuel_kg, double map_pa, double t_ind_ref) noexcept {
  FuelPoint x;
  x.fuel_kg = fuel_kg;
  x.map_pa = map_pa;
  return learn(x, t_ind_ref);
}

bool FuelTorque::learn(const FuelPoint& x, double t_ind_ref, double extra_sd_nm, bool shared_bias) noexcept {
  if (!std::isfinite(x.fuel_kg) || !std::isfinite(x.map_pa) || !std::isfinite(x.rpm) ||
      !std::isfinite(t_ind_ref) || !std::isfinite(extra_sd_nm) || !(x.fuel_kg > 0.0) ||
      (x.spark_valid && !std::isfinite(x.spark_deg)) || (x.lambda_valid && !std::isfinite(x.lambda)))
    return false;
  const Regressor reg = regressor(x);
  double pred = -reg.offset;
  for (int i = 0; i < kN; ++i)
    pred += reg.phi[static_cast<std::size_t>(i)] * st_.theta[static_cast<std::size_t>(i)];
  const double err = t_ind_ref - pred;
  const double r = params_.residual_sd_nm * params_.residual_sd_nm + extra_sd_nm * extra_sd_nm;
  // The shared bias b (consider parameter, variance vb): the reference is φ·θ − offset + b + noise, so its
  // a-priori variance beyond the noise is φᵀPφ + 2φᵀP_θb + vb (the augmented covariance's quadratic form:
  // ≥ 0 as a whole, not term by term).
  const double vb = shared_bias ? params_.shared_bias_sd_nm * params_.shared_bias_sd_nm : 0.0;
  double phi_pxb = 0.0;
  for (int i = 0; i < kN; ++i)
    phi_pxb += reg.phi[static_cast<std::size_t>(i)] * st_.pxb[static_cast<std::size_t>(i)];
  const double sp = std::max(0.0, param_var(reg) + (shared_bias ? 2.0 * phi_pxb + vb : 0.0));
  // 5σ outlier gate once learned: the residual scale (never below one reference's own noise) plus the
  // parameter (and shared-bias) uncertainty here (a new operating point far from the references is not an
  // outlier).
  if (valid() && err * err > 25.0 * (std::max(st_.resid_var, r) + sp)) {
    if (!gated_run(err)) return false;
    relearn();  // consistent on one side: what was learned is wrong (or the engine changed)
    return learn(x, t_ind_ref, extra_sd_nm, shared_bias);
  }
  gated_ = 0;
  if (!update(reg.phi, err, r, shared_bias ? vb : -1.0, phi_pxb)) return false;
  count_reference(x, err, sp);
  return true;
}

// RLS with forgetting λ as a Kalman step on P/λ (the stored P is the posterior), the shared bias b carried
// as a consider parameter (Simon 2006 §7.5): b's variance vb stays, cov(θ, b) is updated. Multiplied through
// by λ: w = Pφ + λP_θb (biased) or Pφ, K = w / (λ(r + 2φᵀP_θb + vb) + φᵀPφ), P ← (P − K wᵀ)/λ,
// P_θb ← P_θb − K(φᵀP_θb + vb) (vb = 0 and no P_θb in w for a reference without the bias). vb < 0: no bias.
bool FuelTorque::update(const std::array<double, kFuelParams>& phi, double err, double r, double vb,
                        double phi_pxb) noexcept {
  const bool biased = vb >= 0.0;
  const double lam = params_.forgetting;
  std::array<double, kN> w{};
  double pv = 0.0;
  for (int i = 0; i < kN; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    for (int j = 0; j < kN; ++j) w[iu] += st_.p[ix(i, j)] * phi[static_cast<std::size_t>(j)];
    pv += phi[iu] * w[iu];
    if (biased) w[iu] += lam * st_.pxb[iu];
  }
  const double denom = std::max(0.0, pv + (biased ? lam * (2.0 * phi_pxb + vb) : 0.0)) + lam * r;
  if (!(denom > 0.0)) return false;
  std::array<double, kN> k{};
  for (int i = 0; i < kN; ++i) k[static_cast<std::size_t>(i)] = w[static_cast<std::size_t>(i)] / denom;
  const std::array<double, kN> prior_theta = prior_state().theta;
  for (int i = 0; i < kN; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    // Within the range: the prior ± range_sd σ.
    const double prior = prior_theta[iu];
    st_.theta[iu] = std::clamp(st_.theta[iu] + k[iu] * err, prior - params_.range_sd * prior_sd_[iu],
                               prior + params_.range_sd * prior_sd_[iu]);
  }
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j)
      st_.p[ix(i, j)] =
          (st_.p[ix(i, j)] - k[static_cast<std::size_t>(i)] * w[static_cast<std::size_t>(j)]) / lam;
  const double pxb_ref = phi_pxb + (biased ? vb : 0.0);
  for (int i = 0; i < kN; ++i)
    st_.pxb[static_cast<std::size_t>(i)] -= k[static_cast<std::size_t>(i)] * pxb_ref;
  cap_covariance();
  refresh_legacy();
  return true;
}

void FuelTorque::count_reference(const FuelPoint& x, double err, double sp) noexcept {
  // Residual variance from the a-priori errors (the gate's scale): EMA until learned, then a running mean
  // over every reference since (weight 1/k floored at sd_ema), as the claimed scale (CoverageScale).
  const bool was_valid = valid();
  ++st_.references;
  auto& c = st_.cells[static_cast<std::size_t>(cell_of(x.rpm, x.map_pa))];
  if (c < 0xFFFF) ++c;
  const double kn = static_cast<double>(st_.references) - params_.min_references;
  const double w = was_valid && kn >= 1.0 ? std::max(1.0 / kn, params_.sd_ema) : params_.sd_ema;
  // The a-priori error holds the parameter (and shared-bias) uncertainty here (variance sp), which the
  // claimed 1σ adds on its own (estimate()): the residual scales take the error shrunk by √(s² / (s² + sp)),
  // s the current scale.
  const double s2 = st_.cover.sd > 0.0 ? st_.cover.sd * st_.cover.sd : st_.resid_var;
  const double e_res = s2 > 0.0 ? err * std::sqrt(s2 / (s2 + sp)) : err;
  st_.resid_var += w * (e_res * e_res - st_.resid_var);
  if (was_valid) observe_coverage(e_res);
}

bool FuelTorque::gated_run(double err) noexcept {
  const int sign = err > 0.0 ? 1 : -1;
  gated_ = sign == gated_sign_ ? gated_ + 1 : 1;
  gated_sign_ = sign;
  return gated_ >= params_.gate_reaccept;
}

void FuelTorque::relearn() noexcept {
  // The parameters stay where they are; their covariance goes back to the prior's and the residual scale is
  // measured again, so the next references move them as freely as the first did. The cell counts stay.
  const FuelTorqueState prior = prior_state();
  st_.p = prior.p;
  st_.pxb = prior.pxb;
  st_.references = 0;
  st_.resid_var = prior.resid_var;
  st_.cover = prior.cover;
  gated_ = 0;
  ++relearns_;
}

void FuelTorque::cap_covariance() noexcept {
  // Symmetrise; forgetting never lets a variance exceed the prior's (D P D with D diagonal keeps P PSD).
  for (int i = 0; i < kN; ++i)
    for (int j = i + 1; j < kN; ++j)
      st_.p[ix(i, j)] = st_.p[ix(j, i)] = 0.5 * (st_.p[ix(i, j)] + st_.p[ix(j, i)]);
  std::array<double, kN> d{};
  for (int i = 0; i < kN; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    const double v = st_.p[ix(i, i)], v0 = prior_sd_[iu] * prior_sd_[iu];
    d[iu] = v > v0 ? std::sqrt(v0 / v) : 1.0;
  }
  for (int i = 0; i < kN; ++i) {
    const auto iu = static_cast<std::size_t>(i);
    for (int j = 0; j < kN; ++j) st_.p[ix(i, j)] *= d[iu] * d[static_cast<std::size_t>(j)];
    st_.pxb[iu] *= d[iu];  // the augmented [P P_θb; P_θbᵀ vb] scaled by diag(D, 1) stays PSD
  }
}

void FuelTorque::observe_coverage(double err) noexcept {
  st_.cover.observe_from(std::sqrt(st_.resid_var), err, params_.sd_ema, params_.sd_floor_nm);
}

void FuelTorque::refresh_legacy() noexcept {
  // η_ref = η_otto (c0 − c1), p_exh V_d/4π = (p_amb + p_off + k_bp x_ref²) V_d/4π: linear maps a, b of θ.
  const double flow = params_.ref_rpm / params_.rated_rpm;
  const std::array<double, kN> a{eta_otto_, -eta_otto_, 0.0, 0.0};
  const std::array<double, kN> b{0.0, 0.0, vd_4pi_, flow * flow * vd_4pi_};
  st_.eta_ref = eta_otto_ * (st_.theta[0] - st_.theta[1]);
  st_.p_exh_nm = (params_.ambient_pa + st_.theta[2] + st_.theta[3] * flow * flow) * vd_4pi_;
  double aa = 0.0, ab = 0.0, bb = 0.0;
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j) {
      const auto iu = static_cast<std::size_t>(i), ju = static_cast<std::size_t>(j);
      aa += a[iu] * st_.p[ix(i, j)] * a[ju];
      ab += a[iu] * st_.p[ix(i, j)] * b[ju];
      bb += b[iu] * st_.p[ix(i, j)] * b[ju];
    }
  st_.p2 = {aa, ab, ab, bb};
  st_.physics = true;
}

void pack(const FuelTorqueState& s, std::array<double, kFuelStateDoubles>& v) noexcept {
  std::size_t k = 0;
  for (double x : s.theta) v[k++] = x;
  for (double x : s.p) v[k++] = x;
  for (double x : s.pxb) v[k++] = x;
  v[k++] = s.resid_var;
  v[k++] = static_cast<double>(s.references);
  v[k++] = s.cover.sd;
  v[k++] = static_cast<double>(s.cover.n);
  for (auto c : s.cells) v[k++] = static_cast<double>(c);
  v[k++] = s.eta_ref;
  v[k++] = s.p_exh_nm;
  for (double x : s.p2) v[k++] = x;
  v[k++] = s.physics ? 1.0 : 0.0;
}

FuelTorqueState unpack(const std::array<double, kFuelStateDoubles>& v) noexcept {
  FuelTorqueState s;
  std::size_t k = 0;
  for (double& x : s.theta) x = v[k++];
  for (double& x : s.p) x = v[k++];
  for (double& x : s.pxb) x = v[k++];
  s.resid_var = v[k++];
  s.references = static_cast<std::uint32_t>(v[k++]);
  s.cover.sd = v[k++];
  s.cover.n = static_cast<std::uint32_t>(v[k++]);
  for (auto& c : s.cells) c = static_cast<std::uint16_t>(v[k++]);
  s.eta_ref = v[k++];
  s.p_exh_nm = v[k++];
  for (double& x : s.p2) x = v[k++];
  s.physics = v[k++] != 0.0;
  return s;
}

FuelTorqueState FuelTorque::from_willans(double eta, double p_exh_nm, const std::array<double, 4>& p2,
                                         double resid_var, std::uint32_t references) const noexcept {
  FuelTorqueState s = prior_state();
  const double flow = params_.ref_rpm / params_.rated_rpm;
  s.theta[0] = eta / eta_otto_ + s.theta[1];
  s.theta[2] = p_exh_nm / vd_4pi_ - params_.ambient_pa - s.theta[3] * flow * flow;
  s.p[ix(0, 0)] = p2[0] / (eta_otto_ * eta_otto_);
  s.p[ix(2, 2)] = p2[3] / (vd_4pi_ * vd_4pi_);
  s.p[ix(0, 2)] = s.p[ix(2, 0)] = 0.5 * (p2[1] + p2[2]) / (eta_otto_ * vd_4pi_);
  s.resid_var = resid_var;
  s.references = references;
  s.physics = true;
  return s;
}

bool FuelTorque::import_state(const FuelTorqueState& in) noexcept {
  FuelTorqueState s = in;
  if (!s.physics) {  // an older file: the two-parameter model's state only
    for (double v : {s.eta_ref, s.p_exh_nm, s.p2[0], s.p2[1], s.p2[2], s.p2[3]})
      if (!std::isfinite(v)) return false;
    const CoverageScale cover = s.cover;
    s = from_willans(s.eta_ref, s.p_exh_nm, s.p2, s.resid_var, s.references);
    s.cover = cover;
  }
  for (double v : s.theta)
    if (!std::isfinite(v)) return false;
  for (double v : s.p)
    if (!std::isfinite(v)) return false;
  for (double v : s.pxb)
    if (!std::isfinite(v)) return false;
  if (!std::isfinite(s.resid_var) || s.resid_var < 0.0) return false;
  if (!std::isfinite(s.cover.sd) || s.cover.sd < 0.0) return false;
  st_ = s;
  cap_covariance();
  bound_shared_bias();
  refresh_legacy();
  return true;
}

void FuelTorque::bound_shared_bias() noexcept {
  // The augmented covariance [P P_θb; P_θbᵀ vb] must stay positive semi-definite: P_θbᵀ P⁻¹ P_θb ≤ vb. A file
  // learned with a larger accessory 1σ than configured now (or none) can break it: P_θb is scaled back onto
  // the bound (zero when no bias is configured).
  const double vb = params_.shared_bias_sd_nm * params_.shared_bias_sd_nm;
  Eigen::Matrix4d p;
  Eigen::Vector4d c;
  for (int i = 0; i < kN; ++i) {
    c(i) = st_.pxb[static_cast<std::size_t>(i)];
    for (int j = 0; j < kN; ++j) p(i, j) = st_.p[ix(i, j)];
  }
  if (c.isZero()) return;
  const Eigen::LDLT<Eigen::Matrix4d> ldlt(p);
  const double q = ldlt.info() == Eigen::Success ? c.dot(ldlt.solve(c)) : -1.0;
  const double f = !(vb > 0.0) || !(q >= 0.0) || !std::isfinite(q) ? 0.0 : q > vb ? std::sqrt(vb / q) : 1.0;
  for (double& x : st_.pxb) x *= f;
}

}  // namespace torqued
