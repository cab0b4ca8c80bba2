#include "fourier_observer.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <sstream>
#include <utility>

#include "table_cache.hpp"

namespace torqued {

namespace {

/// l_j of (CF-10): l_0 = L_a0, l_{2i−1} = l_{2i} = i L_ref (CF §V.B tuning rule).
double gain_of(const FourierParams& p, int j) {
  if (j == 0) return p.l_a0;
  const int i = (j + 1) / 2;
  return i * p.l_ref;
}

/// f_j(α) with f_0 = 1, f_{2i−1} = cos(iα/2), f_{2i} = sin(iα/2) (CF §III).
double basis_of(int j, double alpha) {
  if (j == 0) return 1.0;
  const int i = (j + 1) / 2;
  return (j % 2 == 1) ? std::cos(i * alpha / 2.0) : std::sin(i * alpha / 2.0);
}

/// f_0..f_{nc−1} at α by the angle-addition recurrence: one sin/cos pair per tooth instead of nc − 1. For
/// the stability checks only (within a few ulp of basis_of; the observer itself uses basis_of).
void basis_row(double alpha, int nc, double* f) {
  f[0] = 1.0;
  const double c1 = std::cos(alpha / 2.0), s1 = std::sin(alpha / 2.0);
  double c = 1.0, s = 0.0;
  for (int j = 1; j + 1 < nc; j += 2) {
    const double cn = c * c1 - s * s1;
    s = s * c1 + c * s1;
    c = cn;
    f[j] = c;
    f[j + 1] = s;
  }
}

/// Two doubles in one register (GCC/Clang vector extension: SSE2 on x86-64, NEON on AArch64).
using Pair = double __attribute__((vector_size(16)));

/// p is 16-byte aligned (rows of an even number of doubles in 16-byte aligned storage): the loads fold into
/// the arithmetic.
inline Pair load_pair(const double* p) noexcept {
  Pair v;
  __builtin_memcpy(&v, __builtin_assume_aligned(p, 16), sizeof v);
  return v;
}

/// The per-tooth pass over the coefficients c (CF-8) with the basis rows f (tooth k) and fo (tooth k_out):
/// returns {Σ c_j f_j before the update, Σ c_j fo_j after it}, c_j ← c_j − de g_j f_j (de = Δ_k e_k). Four
/// coefficients per step in two registers, each sum kept as four partial sums added at the end: about half
/// the instructions of the one-at-a-time loop; the sums differ from the sequential ones only by rounding (a
/// few ulp). n is a multiple of 4 (rows padded with zeros); every pointer is 16-byte aligned.
std::pair<double, double> coefficient_pass(double* __restrict c, const double* __restrict f,
                                           const double* __restrict fo, const double* __restrict g, int n,
                                           double de) noexcept {
  Pair ma = {0.0, 0.0}, mb = ma, na = ma, nb = ma;
  const Pair dev = {de, de};
  // Two steps per loop turn: a turn's count, compare and branch were a seventh of the pass (n = 28 by
  // default); unrolled 4 was slower (the remainder code), and the sums keep their order either way.
#pragma GCC unroll 2
  for (int j = 0; j < n; j += 4) {
    const Pair c0 = load_pair(c + j), c1 = load_pair(c + j + 2);
    const Pair f0 = load_pair(f + j), f1 = load_pair(f + j + 2);
    ma += c0 * f0;
    mb += c1 * f1;
    const Pair n0 = c0 - dev * (load_pair(g + j) * f0);
    const Pair n1 = c1 - dev * (load_pair(g + j + 2) * f1);
    __builtin_memcpy(__builtin_assume_aligned(c + j, 16), &n0, sizeof n0);
    __builtin_memcpy(__builtin_assume_aligned(c + j + 2, 16), &n1, sizeof n1);
    na += n0 * load_pair(fo + j);
    nb += n1 * load_pair(fo + j + 2);
  }
  const Pair m = ma + mb, t = na + nb;
  return {m[0] + m[1], t[0] + t[1]};
}

}  // namespace

FourierObserver::FourierObserver(const EngineGeometry& engine, const WheelGeometry& wheel,
                                 const FourierParams& params)
    : params_(params), table_(ToothAngleTable::build(engine, wheel)) {
  const int nh = std::clamp(params_.harmonics, 1, kMaxHarmonics);  // loader rejects; guard anyway
  nc_ = 2 * nh + 1;
  ncp_ = (nc_ + 3) / 4 * 4;
  basis_.assign(static_cast<std::size_t>(table_.samples * ncp_), 0.0);
  for (int k = 0; k < table_.samples; ++k) {
    const double alpha = table_.edge_rad[static_cast<std::size_t>(k)] - engine.tdc_offset_rad;
    for (int j = 0; j < nc_; ++j) basis_[static_cast<std::size_t>(k * ncp_ + j)] = basis_of(j, alpha);
  }
  FourierParams model_gains = params_;
  model_gains.l_ref = params_.model_l_ref;
  for (int j = 0; j < nc_; ++j) {
    l_[static_cast<std::size_t>(j)] = gain_of(params_, j);
    lm_[static_cast<std::size_t>(j)] = gain_of(model_gains, j);
  }
  ref_speed_ = params_.gain_ref_rpm * std::numbers::pi / 30.0;
  lag_ = std::clamp(params_.output_lag, 0, kMaxLag);
  reset();
}

namespace {
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// r0 += a rj and rj −= b p0 element by element (rj read before its update, as in the row expressions).
void row_step(double* __restrict r0, double* __restrict rj, const double* __restrict p0, int n, double a,
              double b) noexcept {
  for (int i = 0; i < n; ++i) {
    r0[i] += a * rj[i];
    rj[i] -= b * p0[i];
  }
}

/// Π_k (I + Ξ_k) over one 720° cycle (CF-12): the observer's error transition.
RowMajor cycle_transition(const FourierParams& params, const EngineGeometry& engine,
                          const WheelGeometry& wheel) {
  const ToothAngleTable t = ToothAngleTable::build(engine, wheel);
  const int nc = 2 * params.harmonics + 1;
  const int n = nc + 1;
  RowMajor phi = RowMajor::Identity(n, n);  // row operations below: contiguous rows
  Eigen::RowVectorXd row0(n);
  std::vector<double> fb(static_cast<std::size_t>(nc));
  for (int k = 0; k < t.samples; ++k) {
    const double alpha = t.edge_rad[static_cast<std::size_t>(k)] - engine.tdc_offset_rad;
    const double d = t.step_rad[static_cast<std::size_t>(k)];
    // Error dynamics (CF-12): x̃_{k+1} = (I + Ξ_k) x̃_k, Ξ_k = Δ_k [[−L_ke, fᵀ], [−l∘f, 0]]. Ξ_k has only a
    // first row and a first column, so (I + Ξ_k) Φ updates Φ's rows in O(n²) instead of a dense O(n³)
    // product (this ran twice per start-up and was an eighth of its instructions).
    row0 = (1.0 - d * params.l_ke) * phi.row(0);
    basis_row(alpha, nc, fb.data());
    for (int j = 0; j < nc; ++j) {
      const double f = fb[static_cast<std::size_t>(j)];
      // row0 += (d f) Φ_{1+j}; Φ_{1+j} −= (d l_j f) Φ_0: one pass over plain rows (Eigen's dynamic-size row
      // expressions were two thirds of the check's instructions), the same operations.
      row_step(row0.data(), phi.row(1 + j).data(), phi.row(0).data(), n, d * f, d * gain_of(params, j) * f);
    }
    phi.row(0) = row0;
  }
  return phi;
}
}  // namespace

double FourierObserver::cycle_spectral_radius(const FourierParams& params, const EngineGeometry& engine,
                                              const WheelGeometry& wheel) {
  const Eigen::EigenSolver<Eigen::MatrixXd> es(Eigen::MatrixXd(cycle_transition(params, engine, wheel)),
                                               false);
  return es.eigenvalues().cwiseAbs().maxCoeff();
}

bool FourierObserver::cycle_contracts(const FourierParams& params, const EngineGeometry& engine,
                                      const WheelGeometry& wheel) {
  // ρ(Φ)^m = ρ(Φ^m) ≤ ‖Φ^m‖ for any induced norm: ‖Φ^m‖∞ < 1 proves ρ < 1 without an eigen-solver (which was
  // most of the start-up's stability check, run twice). Φ, Φ², Φ⁴, … up to Φ^1024; the bound ½ leaves a wide
  // margin for rounding. False: not shown this way (the caller computes ρ).
  constexpr int kSquarings = 10;
  constexpr double kBound = 0.5;
  RowMajor m = cycle_transition(params, engine, wheel);
  for (int i = 0;; ++i) {
    const double norm = m.cwiseAbs().rowwise().sum().maxCoeff();
    if (norm < kBound) return true;
    if (i == kSquarings || !std::isfinite(norm)) return false;
    m = (m * m).eval();
  }
}

namespace {
/// Every input of check_stability() (the configuration loader and the pipeline both check the same gains).
std::uint64_t stability_key(const FourierParams& p, const EngineGeometry& e, const WheelGeometry& w) {
  TableKey k;
  k.add(p.harmonics).add(p.l_ke).add(p.l_a0).add(p.l_ref).add(p.model_l_ref).add(p.gas_model);
  k.add(e).add(w);
  return k.value();
}
}  // namespace

std::optional<std::string> FourierObserver::check_stability(const FourierParams& params,
                                                            const EngineGeometry& engine,
                                                            const WheelGeometry& wheel) {
  // Start-up only: the last answer is kept, so a second check of the same gains costs nothing.
  static std::mutex mu;
  static std::optional<std::pair<std::uint64_t, std::optional<std::string>>> last;
  const std::uint64_t key = stability_key(params, engine, wheel);
  {
    const std::lock_guard lk(mu);
    if (last && last->first == key) return last->second;
  }
  std::optional<std::string> result = check_stability_uncached(params, engine, wheel);
  const std::lock_guard lk(mu);
  last.emplace(key, result);
  return result;
}

std::optional<std::string> FourierObserver::check_stability_uncached(const FourierParams& params,
                                                                     const EngineGeometry& engine,
                                                                     const WheelGeometry& wheel) {
  std::ostringstream why;
  if (params.harmonics < 1 || params.harmonics > kMaxHarmonics) {
    why << "fourier.harmonics = " << params.harmonics << " outside [1, " << kMaxHarmonics << "]";
    return why.str();
  }
  const ToothAngleTable t = ToothAngleTable::build(engine, wheel);
  const int nc = 2 * params.harmonics + 1;
  if (nc >= t.samples) {
    why << "fourier.harmonics = " << params.harmonics << ": 2 n_h + 1 = " << nc << " must be below the "
        << t.samples << " samples per cycle of this wheel";
    return why.str();
  }
  if (!(params.l_ke > 0.0) || !(params.l_a0 > 0.0) || !(params.l_ref > 0.0)) {
    why << "fourier gains must be strictly positive (l_ke = " << params.l_ke << ", l_a0 = " << params.l_a0
        << ", l_ref = " << params.l_ref << ")";
    return why.str();
  }
  // (CF-14): L_ke > (Δα/2) Σ_k l_k f_k(n)² for every sample n of the cycle.
  std::vector<double> fb(static_cast<std::size_t>(nc));
  for (int k = 0; k < t.samples; ++k) {
    const double alpha = t.edge_rad[static_cast<std::size_t>(k)] - engine.tdc_offset_rad;
    const double d = t.step_rad[static_cast<std::size_t>(k)];
    double sum = 0.0;
    basis_row(alpha, nc, fb.data());
    for (int j = 0; j < nc; ++j) {
      const double f = fb[static_cast<std::size_t>(j)];
      sum += gain_of(params, j) * f * f;
    }
    const double bound = 0.5 * d * sum;
    if (!(params.l_ke > bound)) {
      why << "fourier gains break the stability condition (CF-14) at tooth " << k
          << ": l_ke = " << params.l_ke << " must exceed (dalpha/2) sum l_k f_k^2 = " << bound
          << " (lower l_a0/l_ref or raise l_ke)";
      return why.str();
    }
  }
  const double rho =
      cycle_contracts(params, engine, wheel) ? 0.0 : cycle_spectral_radius(params, engine, wheel);
  if (!(rho < 1.0)) {
    why << "fourier gains give an unstable observer over one cycle: spectral radius of the error transition "
        << rho << " >= 1 (lower fourier.harmonics or l_ref; keep l_ke * dalpha well below 2)";
    return why.str();
  }
  if (params.gas_model) {  // the observer also runs with model_l_ref while the gas model is valid
    FourierParams m = params;
    m.l_ref = params.model_l_ref;
    m.gas_model = false;
    if (auto w = check_stability_uncached(m, engine, wheel))
      return "with the gas model (l_ref = model_l_ref): " + *w;
  }
  return std::nullopt;
}

void FourierObserver::reset() noexcept {
  c_.fill(0.0);
  phi_ = 0.0;
  mean_speed_ = 0.0;
  est_ = TorqueEstimate{};
  est_.health = Health::kNotConverged;
  est_tooth_ = 0;
  expected_tooth_ = -1;
  teeth_seen_ = 0;
  edge_t_ns_.fill(0);
  model_.fill(0.0);
}

void FourierObserver::push_model(double ripple_nm) noexcept {
  model_.push(std::isfinite(ripple_nm) ? ripple_nm : 0.0);
}

double FourierObserver::net_torque_at(int k) const noexcept {
  const double* f = &basis_[static_cast<std::size_t>(k * ncp_)];
  double t = 0.0;
  for (int j = 0; j < nc_; ++j) t += c_[static_cast<std::size_t>(j)] * f[j];
  return t;
}

bool FourierObserver::update(const ToothSample& s) noexcept {
  const int kk = table_.samples;
  if (const Health input = check_tooth_sample(s, kk); input != Health::kValid) {
    ++stats_.rejected;
    expected_tooth_ = -1;
    est_.health = input;
    return false;
  }
  return update_checked(s);
}

// update() after check_tooth_sample (AnglePipeline::on_tooth makes the same checks once per tooth).
bool FourierObserver::update_checked(const ToothSample& s) noexcept {
  const int kk = table_.samples;
  const int k = s.tooth;
  const double omega = s.width_rad / s.dt_s;
  const double phi_meas = 0.5 * table_.j_center[static_cast<std::size_t>(k)] * omega * omega;
  if (expected_tooth_ >= 0 && k != expected_tooth_) {
    const int missing = (k - expected_tooth_ + kk) % kk;
    ++stats_.skipped_teeth;
    if (missing > kk / 8) {
      expected_tooth_ = -1;
    } else {
      for (int m = 0; m < missing; ++m) {  // lost teeth: integrate the model open loop (CF-7)
        const int km = (expected_tooth_ + m) % kk;
        phi_ += table_.step_rad[static_cast<std::size_t>(km)] * net_torque_at(km);  // model ripple unknown: 0
        push_model(0.0);
      }
    }
  }
  if (expected_tooth_ < 0) {
    phi_ = phi_meas;  // restart from the measured energy; keep the coefficients (warm start)
    teeth_seen_ = 0;
    mean_speed_ = omega;
  }
  mean_speed_ += (omega - mean_speed_) / kk;
  // Beyond the paper: scale the gains by (ω_ref/ω̄)² above ω_ref, so that the energy innovation, whose noise
  // from edge-angle error grows as θ̇², moves the coefficients by the same relative amount at every speed.
  double scale = 1.0;
  if (ref_speed_ > 0.0 && mean_speed_ > ref_speed_)
    scale = (ref_speed_ / mean_speed_) * (ref_speed_ / mean_speed_);
  const double d = table_.step_rad[static_cast<std::size_t>(k)] * scale;
  const double err = phi_ - phi_meas;  // (CF-8): L_n (ŷ_n − y_n) = Δα [L_ke, l_j f_j]ᵀ (φ̂ − ½ J y)
  // Torque at e_k reaches the energy error only at later teeth: evaluating the waveform `lag` teeth back with
  // the newest coefficients is a fixed-lag smoother (beyond the paper).
  const int k_out = k >= lag_ ? k - lag_ : k - lag_ + kk;  // (k − lag) mod K without a division
  // One pass over the coefficients: the model torque at e_k with the coefficients before this tooth, their
  // update (CF-8), and the output torque at e_{k_out} with the updated ones.
  model_active_ = params_.gas_model && model_next_valid_;
  const std::array<double, kCoeffStride>& gains = model_active_ ? lm_ : l_;  // model valid: model_l_ref
  const auto [t_model, t_net] =
      coefficient_pass(c_.data(), &basis_[static_cast<std::size_t>(k * ncp_)],
                       &basis_[static_cast<std::size_t>(k_out * ncp_)], gains.data(), ncp_, d * err);
  push_model(model_next_valid_ ? model_next_ : 0.0);
  phi_ += table_.step_rad[static_cast<std::size_t>(k)] * (t_model + model_[0] - params_.l_ke * err);
  ++stats_.updates;
  ++teeth_seen_;
  edge_t_ns_.push(s.t_ns);
  if (!std::isfinite(phi_) || !std::isfinite(t_net)) {
    ++stats_.resets;
    reset();
    est_.health = Health::kNumerical;
    return false;
  }
  est_.t_ns = edge_t_ns_[static_cast<std::size_t>(lag_)];
  est_.torque_nm = t_net + model_[static_cast<std::size_t>(lag_)] + load_star_nm_;
  est_.uncertainty = 0.0;
  est_tooth_ = k_out;
  est_.health = (teeth_seen_ >= 2 * kk && wheel_learned_) ? Health::kValid : Health::kNotConverged;
  expected_tooth_ = k + 1 == kk ? 0 : k + 1;
  return true;
}

}  // namespace torqued
