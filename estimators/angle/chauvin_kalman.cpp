#include "chauvin_kalman.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "table_cache.hpp"

namespace torqued {

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kRpm = std::numbers::pi / 30.0;
/// With differenced edge noise, the white part of R as a fraction of the full edge-noise variance: what the
/// MA(1) model leaves out (timestamp quantisation, a non-white part of the tooth-table residual), and it
/// keeps the innovation variance away from zero.
constexpr double kWhiteFloorFrac = 1e-2;

/// v.allFinite() with one vectorised sum on the usual path: a sum of finite values is finite unless it
/// overflows (then every element is checked), and any infinite or NaN element makes the sum non-finite.
/// Eigen's allFinite() tests the 16 elements one by one with a branch each (a seventh of an update).
bool all_finite(const ChauvinKalman::Vec& v) noexcept { return std::isfinite(v.sum()) || v.allFinite(); }

using Pair = double __attribute__((vector_size(16)));  // two doubles in one register (SSE2 / NEON)

/// The lag block of riccati_step_symmetric(): rows and columns 2…13 of the new P (column-major, stride
/// kStates) are the old P and the gain product shifted by one state in both indices, P(r, c) = P(r−1, c−1) −
/// (K_{r−1} K_{c−1}) S. Computed on and below the diagonal two rows at a time (from the even row at or above
/// c) and written to both triangles: P is bit-symmetric and K_a K_b = K_b K_a exactly, so every entry has the
/// bits of its own expression (tests: SymmetricRiccatiStepIsTheGeneralStepBitForBit), with 42 row pairs
/// instead of 72. Columns from the last down: column c reads rows c − 2…12 of column c − 1, which no earlier
/// write touches (they go to columns above c − 1). A column's first pair needs no mirror: its entries are the
/// diagonal and either the entry above it (computed here) or the one below it (computed in column c + 1's
/// first pair).
void shift_lag_block(double* p, const double* __restrict k, double s) noexcept {
  constexpr int n = ChauvinKalman::kStates;
  constexpr int first = ChauvinKalman::kTorquePrevState, last = ChauvinKalman::kTorqueLastState;
  static_assert(first % 2 == 0 && (last - first + 1) % 2 == 0, "row pairs start on the block's first row");
  const Pair sv = {s, s};
#pragma GCC unroll 12
  for (int c = last; c >= first; --c) {
    const Pair kc = {k[c - 1], k[c - 1]};
    const int r0 = c - ((c - first) & 1);
#pragma GCC unroll 6
    for (int r = r0; r < last; r += 2) {
      Pair old, kr;
      std::memcpy(&old, p + (c - 1) * n + (r - 1), sizeof old);
      std::memcpy(&kr, k + (r - 1), sizeof kr);
      const Pair v = old - (kr * kc) * sv;
      std::memcpy(p + c * n + r, &v, sizeof v);
      if (r > r0) {
        p[r * n + c] = v[0];
        p[(r + 1) * n + c] = v[1];
      }
    }
  }
}
}  // namespace

ChauvinKalman::ChauvinKalman(const EngineGeometry& engine, const WheelGeometry& wheel,
                             const KalmanParams& params)
    : params_(params), table_(ToothAngleTable::build(engine, wheel)) {
  params_.smoother_lag = std::clamp(params_.smoother_lag, 0, kMaxLag);  // config loader rejects; guard anyway
  edge_sd_rad_ = params_.edge_noise_deg * kDeg;
  const int kk = table_.samples;
  a11_.resize(static_cast<std::size_t>(kk));
  b12_.resize(static_cast<std::size_t>(kk));
  acol_.resize(static_cast<std::size_t>(2 * kk));
  qgain_.resize(static_cast<std::size_t>(2 * kk));
  // The pole per noise set: δ for the whole net torque, model_delta for the gas model's miss (its correlation
  // length after the burn is modelled is shorter; docs/angle_estimators.md "A pole of its own").
  const std::array<double, 2> delta{params_.delta, params_.model_delta};
  for (int k = 0; k < kk; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const auto n = static_cast<std::size_t>((k + 1) % kk);
    // Energy balance over Δ_k (CF-2), the exact form of (CK-3): ½J_{k+1}x1(k+1) = ½J_k x1(k) + Δ_k x2(k).
    a11_[i] = table_.j_center[i] / table_.j_center[n];
    b12_[i] = 2.0 * table_.step_rad[i] / table_.j_center[n];
    for (int set = kWholeTorqueSet; set <= kModelMissSet; ++set) {
      const auto j = static_cast<std::size_t>(set * kk + k);
      // The pole of h(z) and the (1−a)⁴ of its noise input (CK-18).
      acol_[j] = std::exp(-delta[static_cast<std::size_t>(set)] * table_.step_rad[i]);
      qgain_[j] = std::pow(1.0 - acol_[j], 4);
    }
  }
  // Q from the stationary variance of x2 under h(z) at the nominal step: for x(n+1) = 2a x(n) − a² x(n−1) +
  // (1−a)² u, var x = (1−a)⁴ q (1+a²)/(1−a²)³  →  q = σ² (1−a²)³ / ((1−a)⁴ (1+a²)). Two σ (and two δ): the
  // whole net torque (no model) and, with gas_model, what the pressure model misses.
  std::vector<double> steps(table_.step_rad);
  std::nth_element(steps.begin(), steps.begin() + kk / 2, steps.end());
  const double nominal_step = steps[static_cast<std::size_t>(kk / 2)];
  const auto stationary = [&](double d, double sd) {
    const double a = std::exp(-d * nominal_step);
    // The ratio first, then σ²: the papers' filter's Q rounds as it did before the model set had a pole of
    // its own.
    return sd * sd * (std::pow(1.0 - a * a, 3) / (std::pow(1.0 - a, 4) * (1.0 + a * a)));
  };
  qu_[kWholeTorqueSet] = stationary(params_.delta, params_.torque_sd_nm);
  qu_[kModelMissSet] = stationary(params_.model_delta, params_.model_torque_sd_nm);
  sd_[kWholeTorqueSet] = params_.torque_sd_nm;
  sd_[kModelMissSet] = params_.model_torque_sd_nm;

  // APS (CK §VI): iterate the periodic Riccati equation to its periodic solution for each speed bin.
  const int bins = std::max(2, params_.speed_bins);
  bin_log_speed_.resize(static_cast<std::size_t>(bins));
  const double l0 = std::log(params_.min_rpm * kRpm), l1 = std::log(params_.max_rpm * kRpm);
  for (int b = 0; b < bins; ++b)
    bin_log_speed_[static_cast<std::size_t>(b)] = l0 + (l1 - l0) * b / (bins - 1);
  bin_scale_ = (bins - 1) / (bin_log_speed_.back() - bin_log_speed_.front());
  inv_samples_ = 1.0 / table_.samples;
  if (params_.periodic_gains) build_aps_tables(bins);
  reset();
}

// Every input of build_aps_set(): the per-tooth model, the noise levels and the speed bins (the code itself
// is the cache's part of the key: learned/table_store.hpp).
std::uint64_t ChauvinKalman::aps_key(int sets, int bins) const noexcept {
  TableKey key;
  key.add(std::string_view("chauvin-aps 3")).add(kStates).add(table_.samples).add(sets).add(bins);
  key.add(params_.smoother_lag);  // the output state whose posterior variance is tabulated
  key.add(table_.width_rad).add(a11_).add(b12_).add(acol_).add(bin_log_speed_);
  key.add(std::span<const double>(qu_)).add(std::span<const double>(sd_));
  key.add(edge_sd_rad_).add(params_.jitter_s).add(params_.differenced_edge_noise).add(kWhiteFloorFrac);
  return key.value();
}

// The APS gain sets (CK §VI), from the table cache when it holds them for these inputs.
void ChauvinKalman::build_aps_tables(int bins) {
  const int sets = params_.gas_model ? kModelMissSet + 1 : kWholeTorqueSet + 1;
  const auto gains = static_cast<std::size_t>(sets * bins * table_.samples);
  const std::size_t n = gains * static_cast<std::size_t>(kStates);
  // The gains live in the cache's own array (kStates doubles per gain), then the output variances (one per
  // gain): read from the cache they are moved in, computed they are stored from where they were built (no
  // copy of the ≈ 1 MB gain table either way); the variances are split off into aps_var_ after.
  aps_var_.assign(gains, 0.0);
  cached_table("chauvin-aps", aps_key(sets, bins), aps_gain_, n + gains, [&](std::vector<double>& t) {
    t.clear();
    t.reserve(n + gains);  // build_aps_set() appends each gain in its first cycle (no zero-fill of ≈ 1 MB)
    for (int set = 0; set < sets; ++set) {
      mode_ = set;
      build_aps_set(set, bins, t);
    }
    mode_ = kWholeTorqueSet;
    t.insert(t.end(), aps_var_.begin(), aps_var_.end());
  });
  aps_var_.assign(aps_gain_.begin() + static_cast<std::ptrdiff_t>(n), aps_gain_.end());
  aps_gain_.resize(n);
}

double ChauvinKalman::measurement_var(int k, double speed_rad_s) const noexcept {
  const double rel = ToothPreprocessor::speed_sq_rel_sd(table_.width_rad[static_cast<std::size_t>(k)],
                                                        speed_rad_s, edge_sd_rad_, params_.jitter_s);
  const double sd = rel * speed_rad_s * speed_rad_s;
  const double frac = params_.differenced_edge_noise ? kWhiteFloorFrac : 1.0;
  return frac * sd * sd + 1e-9;
}

double ChauvinKalman::edge_coupling(int k) const noexcept {
  if (!params_.differenced_edge_noise) return 0.0;
  return 1.0 / table_.width_rad[static_cast<std::size_t>(k)];
}

double ChauvinKalman::edge_state_var(double speed_rad_s) const noexcept {
  if (!params_.differenced_edge_noise) return 0.0;
  // y = (w/dt)² with an edge error e (angle, or ω × time): ∂y/∂e = 2θ̇²/w per edge; σ_e² = σ_a² + ω²σ_t², the
  // same edge variance measurement_var() counts twice for the two edges of a period.
  const double w2 = speed_rad_s * speed_rad_s;
  return 4.0 * w2 * w2 * (edge_sd_rad_ * edge_sd_rad_ + w2 * params_.jitter_s * params_.jitter_s);
}

// One APS gain set (mode_ = set selects its Q): per speed bin, the periodic Riccati solution's gains,
// appended to `out` (which holds the sets before this one, kStates doubles per slot) and their output
// variances written into aps_var_.
void ChauvinKalman::build_aps_set(int set, int bins, std::vector<double>& out) {
  const int kk = table_.samples;
  const int o = kTorqueState + params_.smoother_lag;
  std::vector<StepNoise> noise(static_cast<std::size_t>(kk));
  for (int b = 0; b < bins; ++b) {
    const double w = std::exp(bin_log_speed_[static_cast<std::size_t>(b)]);
    for (int k = 0; k < kk; ++k) noise[static_cast<std::size_t>(k)] = step_noise(k, w);
    Mat p = initial_covariance(0, w);
    Vec g;
    double change = 1.0;
    for (int cycle = 0; cycle < 500 && change > 1e-12; ++cycle) {
      change = 0.0;
      for (int k = 0; k < kk; ++k) {
        const auto slot_index = static_cast<std::size_t>((set * bins + b) * kk + k);
        const double prior_oo = p(o, o),
                     pc_o = p(o, kSpeedSqState) +
                            noise[static_cast<std::size_t>(k)].h * (p(o, kNoisePrev) - p(o, kNoiseNow));
        riccati_step_symmetric(k, noise[static_cast<std::size_t>(k)], p,
                               g);                      // P bit-symmetric: P0 is diagonal
        aps_var_[slot_index] = prior_oo - g(o) * pc_o;  // posterior variance of the output state x2(k−d | k)
        if (!(change > 1e-12)) {  // once a gain of this cycle moved, the cycle is not the last: skip the rest
          const double scale = std::max(1e-300, g.cwiseAbs().maxCoeff());
          // The first cycle compares with zeros (the slot is appended below, not zero-filled first).
          const double moved =
              cycle == 0 ? g.cwiseAbs().maxCoeff()
                         : (g - Eigen::Map<const Vec>(&out[slot_index * kStates])).cwiseAbs().maxCoeff();
          change = std::max(change, moved / scale);
        }
        if (cycle == 0)  // slots are appended in index order: set, bin, tooth
          out.insert(out.end(), g.data(), g.data() + kStates);
        else
          Eigen::Map<Vec>{&out[slot_index * kStates]} = g;
      }
    }
  }
}

ChauvinKalman::Mat ChauvinKalman::initial_covariance(int k, double speed_rad_s) const noexcept {
  const double sd = sd_[static_cast<std::size_t>(mode_)];
  Mat p = Mat::Identity() * sd * sd;
  const double v = edge_state_var(speed_rad_s);
  const double h = edge_coupling(k);
  p(kSpeedSqState, kSpeedSqState) = measurement_var(k, speed_rad_s) + 2.0 * h * h * v;
  p(kNoiseNow, kNoiseNow) = v;
  p(kNoisePrev, kNoisePrev) = v;
  return p;
}

void ChauvinKalman::add_process_noise(int k, double speed_rad_s, Mat& p) const noexcept {
  p(kTorqueState, kTorqueState) += qgain_[set_slot(k)] * qu_[static_cast<std::size_t>(mode_)];
  p(kNoiseNow, kNoiseNow) += edge_state_var(speed_rad_s);  // the next edge's error, fresh
}

ChauvinKalman::Mat ChauvinKalman::transition(int k) const noexcept {
  const auto i = static_cast<std::size_t>(k);
  const double a = acol_[set_slot(k)];
  Mat m = Mat::Zero();
  m(kSpeedSqState, kSpeedSqState) = a11_[i];
  m(kSpeedSqState, kTorqueState) = b12_[i];
  m(kTorqueState, kTorqueState) = 2.0 * a;
  m(kTorqueState, kTorquePrevState) = -a * a;
  for (int j = kTorquePrevState; j <= kTorqueLastState; ++j) m(j, j - 1) = 1.0;  // shift register of past x2
  m(kNoisePrev, kNoiseNow) = 1.0;  // v_k becomes v_{k−1}; v_{k+1} is fresh noise
  return m;
}

ChauvinKalman::Mat ChauvinKalman::propagate(int k, const Mat& p) const noexcept {
  // A P Aᵀ with the sparse A_k of transition(): the rows of θ̇² and x2(k) have two entries, the rest is a
  // shift register. Same products as the dense form, without the 2·8³ multiplications by zero (per tooth).
  const auto i = static_cast<std::size_t>(k);
  const double a = acol_[set_slot(k)];
  const double r00 = a11_[i], r01 = b12_[i], r11 = 2.0 * a, r12 = -a * a;
  Mat m;  // m = A P
  m.row(kSpeedSqState) = r00 * p.row(kSpeedSqState) + r01 * p.row(kTorqueState);
  m.row(kTorqueState) = r11 * p.row(kTorqueState) + r12 * p.row(kTorquePrevState);
  for (int r = kTorquePrevState; r <= kTorqueLastState; ++r) m.row(r) = p.row(r - 1);
  m.row(kNoiseNow).setZero();
  m.row(kNoisePrev) = p.row(kNoiseNow);
  Mat out;  // out = m Aᵀ: column j of out = m · (row j of A)ᵀ
  out.col(kSpeedSqState) = r00 * m.col(kSpeedSqState) + r01 * m.col(kTorqueState);
  out.col(kTorqueState) = r11 * m.col(kTorqueState) + r12 * m.col(kTorquePrevState);
  for (int c = kTorquePrevState; c <= kTorqueLastState; ++c) out.col(c) = m.col(c - 1);
  out.col(kNoiseNow).setZero();
  out.col(kNoisePrev) = m.col(kNoiseNow);
  return out;
}

void ChauvinKalman::riccati_step(int k, double speed_rad_s, Mat& p, Vec& gain) const noexcept {
  // (CK-12): filter gain K = P Cᵀ (C P Cᵀ + R)⁻¹ with C = [1 0 … 0 −h h] (C = [1 0 … 0] in the paper, h = 0
  // without differenced edge noise); the predictor gain is L = A K.
  const double h = edge_coupling(k);
  const Vec pc = p.col(kSpeedSqState) + h * (p.col(kNoisePrev) - p.col(kNoiseNow));
  const double s = pc(kSpeedSqState) + h * (pc(kNoisePrev) - pc(kNoiseNow)) + measurement_var(k, speed_rad_s);
  gain = pc / s;
  // (CK-13): P_{k+1} = A (P − K S Kᵀ) Aᵀ + B Q Bᵀ.
  // P − K S Kᵀ column by column ((K_i K_j) S: the same values as the dense expression, no temporaries).
  Mat post;
  for (int j = 0; j < kStates; ++j) post.col(j) = p.col(j) - (gain * gain(j)) * s;
  p = propagate(k, post);
  add_process_noise(k, speed_rad_s, p);
  // Keep symmetric (docs/conventions.md habit 12): ½(P + Pᵀ) element by element over one triangle (the same
  // values as the dense expression, half the work and no temporary; the diagonal is unchanged by it).
  for (int j = 1; j < kStates; ++j) {
    for (int i = 0; i < j; ++i) {
      const double v = 0.5 * (p(i, j) + p(j, i));
      p(i, j) = v;
      p(j, i) = v;
    }
  }
}

ChauvinKalman::StepNoise ChauvinKalman::step_noise(int k, double speed_rad_s) const noexcept {
  return {edge_coupling(k), measurement_var(k, speed_rad_s),
          qgain_[set_slot(k)] * qu_[static_cast<std::size_t>(mode_)], edge_state_var(speed_rad_s)};
}

void ChauvinKalman::riccati_step_symmetric(int k, double speed_rad_s, Mat& p, Vec& gain) const noexcept {
  riccati_step_symmetric(k, step_noise(k, speed_rad_s), p, gain);
}

void ChauvinKalman::riccati_step_symmetric(int k, const StepNoise& n, Mat& p, Vec& gain) const noexcept {
  // riccati_step() with A P Aᵀ written out for a symmetric P. Rows 2…13 and 15 of A_k copy one state (the lag
  // register, v_k → v_{k−1}), row 14 is zero and only rows 0 and 1 combine two: A post Aᵀ is post shifted by
  // one state in both indices, except rows and columns 0 and 1, which are m0 = (A post) row 0 and m1 = row 1
  // (each the same sum of the same two products as in propagate()). The product of a copy row and a
  // combining row comes out equal from both sides, so of the ½(P + Pᵀ) only the (0, 1) entry changes
  // anything. A third of riccati_step()'s instructions; same bits for a bit-symmetric P.
  const double h = n.h;
  const Vec pc = p.col(kSpeedSqState) + h * (p.col(kNoisePrev) - p.col(kNoiseNow));
  const double s = pc(kSpeedSqState) + h * (pc(kNoisePrev) - pc(kNoiseNow)) + n.r;
  gain = pc / s;
  // Columns of post = P − K S Kᵀ (its entries as in riccati_step(), (K_i K_j) S) that A post Aᵀ reads outside
  // the shifted block; that block is then written in place by shift_lag_block() (its lower triangle,
  // mirrored), without a temporary matrix.
  const Vec post0 = p.col(kSpeedSqState) - (gain * gain(kSpeedSqState)) * s;
  const Vec post1 = p.col(kTorqueState) - (gain * gain(kTorqueState)) * s;
  const Vec post2 = p.col(kTorquePrevState) - (gain * gain(kTorquePrevState)) * s;
  const Vec post14 = p.col(kNoiseNow) - (gain * gain(kNoiseNow)) * s;
  const auto i = static_cast<std::size_t>(k);
  const double a = acol_[set_slot(k)];
  const double r00 = a11_[i], r01 = b12_[i], r11 = 2.0 * a, r12 = -a * a;
  const Vec m0 = r00 * post0 + r01 * post1;  // post symmetric: rows = columns
  const Vec m1 = r11 * post1 + r12 * post2;
  constexpr int kLags = kTorqueLastState - kTorquePrevState + 1;  // the copy rows 2…13
  shift_lag_block(p.data(), gain.data(), s);
  p.block<kLags, 1>(kTorquePrevState, kNoisePrev) = post14.segment<kLags>(kTorqueState);
  p.block<1, kLags>(kNoisePrev, kTorquePrevState) = post14.segment<kLags>(kTorqueState).transpose();
  p(kNoisePrev, kNoisePrev) = post14(kNoiseNow);
  p.row(kNoiseNow).setZero();
  p.col(kNoiseNow).setZero();
  for (const int r : {kSpeedSqState, kTorqueState}) {
    const Vec& m = r == kSpeedSqState ? m0 : m1;
    p.block<kLags, 1>(kTorquePrevState, r) = m.segment<kLags>(kTorqueState);
    p.block<1, kLags>(r, kTorquePrevState) = m.segment<kLags>(kTorqueState).transpose();
    p(kNoisePrev, r) = m(kNoiseNow);
    p(r, kNoisePrev) = m(kNoiseNow);
  }
  p(kSpeedSqState, kSpeedSqState) = r00 * m0(kSpeedSqState) + r01 * m0(kTorqueState);
  p(kTorqueState, kTorqueState) = r11 * m1(kTorqueState) + r12 * m1(kTorquePrevState);
  const double v01 = r11 * m0(kTorqueState) + r12 * m0(kTorquePrevState);  // (A post Aᵀ)(0, 1)
  const double v10 = r00 * m1(kSpeedSqState) + r01 * m1(kTorqueState);     // (A post Aᵀ)(1, 0)
  p(kTorqueState, kTorqueState) += n.q;  // add_process_noise() with the values of this tooth and speed
  p(kNoiseNow, kNoiseNow) += n.v;
  p(kSpeedSqState, kTorqueState) = p(kTorqueState, kSpeedSqState) = 0.5 * (v01 + v10);
}

ChauvinKalman::Vec ChauvinKalman::periodic_gain(int k, double speed_rad_s) const noexcept {
  Vec g;
  periodic_gain_into(k, speed_rad_s, g);
  return g;
}

ChauvinKalman::BinPos ChauvinKalman::bin_pos(int k, double speed_rad_s) const noexcept {
  return bin_pos_log(k, std::log(std::max(speed_rad_s, 1e-3)));
}

ChauvinKalman::Vec ChauvinKalman::periodic_gain_of_set(int set, int k, double speed_rad_s) const noexcept {
  const int built = params_.gas_model ? kModelMissSet : kWholeTorqueSet;  // last set build_aps_tables made
  const BinPos at =
      bin_pos_log(std::clamp(set, kWholeTorqueSet, built), k, std::log(std::max(speed_rad_s, 1e-3)));
  return (1.0 - at.t) * aps_gain(at.lo) + at.t * aps_gain(at.hi);
}

ChauvinKalman::BinPos ChauvinKalman::bin_pos_log(int set, int k, double l) const noexcept {
  const int kk = table_.samples;
  const int bins = static_cast<int>(bin_log_speed_.size());
  double pos = (l - bin_log_speed_.front()) * bin_scale_;
  pos = std::clamp(pos, 0.0, static_cast<double>(bins - 1) - 1e-12);
  const int b = static_cast<int>(pos);
  const int base = set * bins;
  return {static_cast<std::size_t>((base + b) * kk + k), static_cast<std::size_t>((base + b + 1) * kk + k),
          pos - b};
}

void ChauvinKalman::periodic_gain_into(int k, double speed_rad_s, Vec& gain) const noexcept {
  (void)periodic_gain_var_into(k, speed_rad_s, gain);
}

// The gain and its output variance from one speed-bin position: one log(ω) per tooth, not two.
double ChauvinKalman::periodic_gain_var_into(int k, double speed_rad_s, Vec& gain) const noexcept {
  const BinPos at = bin_pos(k, speed_rad_s);
  gain = (1.0 - at.t) * aps_gain(at.lo) + at.t * aps_gain(at.hi);
  return (1.0 - at.t) * aps_var_[at.lo] + at.t * aps_var_[at.hi];
}

double ChauvinKalman::periodic_output_var(int k, double speed_rad_s) const noexcept {
  const BinPos at = bin_pos(k, speed_rad_s);
  return (1.0 - at.t) * aps_var_[at.lo] + at.t * aps_var_[at.hi];
}

void ChauvinKalman::reset() noexcept {
  x_.setZero();
  p_.setZero();
  p_finite_ = true;
  last_gain_.setZero();
  last_innovation_ = 0.0;
  output_model_nm_ = 0.0;
  est_ = TorqueEstimate{};
  est_.health = Health::kNotConverged;
  est_tooth_ = 0;
  mean_speed_ = 0.0;
  expected_tooth_ = -1;
  teeth_seen_ = 0;
  edge_t_ns_.fill(0);
  model_.fill(0.0);
  mode_ = kWholeTorqueSet;
}

void ChauvinKalman::advance_mean_speed(double omega) noexcept {
  const double old = mean_speed_;
  mean_speed_ += (omega - mean_speed_) * inv_samples_;
  // ln ω̄ by ln(ω̄/ω̄_old) = ln(1 + u), u = (ω̄ − ω̄_old)/ω̄_old: |u| ≲ 1e-3 per tooth (the mean moves by a
  // K-th of the in-cycle speed ripple), so four terms leave ≤ |u|⁵/5 ≈ 1e-16 per tooth; exact once per cycle
  // (and after a restart or a large step) so rounding cannot accumulate. Replaces a std::log per tooth.
  const double u = (mean_speed_ - old) / old;
  if (++log_fresh_teeth_ >= table_.samples || !(std::abs(u) < 1e-2) || !(old > 1e-3) ||
      !(mean_speed_ > 1e-3)) {
    log_mean_speed_ = std::log(std::max(mean_speed_, 1e-3));
    log_fresh_teeth_ = 0;
    return;
  }
  log_mean_speed_ += u * (1.0 - u * (0.5 - u * (1.0 / 3.0 - 0.25 * u)));
}

void ChauvinKalman::predict(int k) noexcept {
  const auto i = static_cast<std::size_t>(k);
  const double a = acol_[set_slot(k)];
  // x ← A_k x with the sparse A_k of the header comment.
  const double x1 = a11_[i] * x_(kSpeedSqState) + b12_[i] * (x_(kTorqueState) + model_[0]);
  const double x2 = 2.0 * a * x_(kTorqueState) - a * a * x_(kTorquePrevState);
  x_(kNoisePrev) = x_(kNoiseNow);
  x_(kNoiseNow) = 0.0;  // the next edge's error: zero mean
  // The lag register moves up one state, through registers (the element loop had become a memmove call).
  constexpr int kLags = kTorqueLastState - kTorquePrevState + 1;
  const Eigen::Matrix<double, kLags, 1> lags = x_.segment<kLags>(kTorqueState);
  x_.segment<kLags>(kTorquePrevState) = lags;
  x_(kTorqueState) = x2;
  x_(kSpeedSqState) = x1;
}

void ChauvinKalman::push_edge_time(std::int64_t t_ns) noexcept { edge_t_ns_.push(t_ns); }

void ChauvinKalman::push_model(double ripple_nm) noexcept {
  model_.push(std::isfinite(ripple_nm) ? ripple_nm : 0.0);
}

// Teeth lost before tooth k: predicted through (no measurement), or a restart when more than 1/8 of the cycle
// is missing.
void ChauvinKalman::bridge_lost_teeth(int k) noexcept {
  const int kk = table_.samples;
  const int missing = (k - expected_tooth_ + kk) % kk;
  ++stats_.skipped_teeth;
  if (missing > kk / 8) {
    expected_tooth_ = -1;
    return;
  }
  for (int m = 0; m < missing; ++m) {
    const int km = (expected_tooth_ + m) % kk;
    push_model(0.0);  // the model's value at a lost tooth is not known here: the prior mean
    predict(km);
    if (!params_.periodic_gains) {  // no measurement at a lost tooth: propagate P only
      p_ = propagate(km, p_);
      add_process_noise(km, mean_speed_, p_);
    }
    push_edge_time(0);  // unknown time of the lost edge
  }
}

bool ChauvinKalman::update(const ToothSample& s) noexcept {
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
bool ChauvinKalman::update_checked(const ToothSample& s) noexcept {
  const int kk = table_.samples;
  const int k = s.tooth;
  const double omega = s.width_rad / s.dt_s;
  const double y = omega * omega;
  if (expected_tooth_ >= 0 && k != expected_tooth_) bridge_lost_teeth(k);
  // The noise set before a restart: the starting covariance takes this tooth's σ, not the last tooth's.
  mode_ = params_.gas_model && model_next_valid_ ? kModelMissSet : kWholeTorqueSet;
  if (expected_tooth_ < 0) {
    // (Re)start: x̂ = [y, 0, ...], P0 = diag(R, σ², ...) (CK (11) initial condition m0).
    x_.setZero();
    x_(kSpeedSqState) = y;
    mean_speed_ = omega;
    log_fresh_teeth_ = table_.samples;  // ln ω̄ exact on this tooth
    p_ = initial_covariance(k, omega);
    p_finite_ = p_.allFinite();
    teeth_seen_ = 0;
  }
  advance_mean_speed(omega);
  push_model(model_next_valid_ ? model_next_ : 0.0);
  Vec& gain = last_gain_;  // the gain is built where it is kept (no per-tooth copy of 16 doubles)
  double out_var = 0.0;
  const int o = kTorqueState + params_.smoother_lag;  // x2(k−d): the smoothed output state
  const double h = edge_coupling(k);
  if (params_.periodic_gains) {
    // The periodic Riccati solution's gain and variance at ln ω̄ (as periodic_gain_var_into(k, ω̄) computes
    // them, with the logarithm kept up to date instead of taken per tooth).
    const BinPos at = bin_pos_log(k, log_mean_speed_);
    gain = (1.0 - at.t) * aps_gain(at.lo) + at.t * aps_gain(at.hi);
    out_var = (1.0 - at.t) * aps_var_[at.lo] + at.t * aps_var_[at.hi];
  } else {
    Mat pn = p_;
    riccati_step(k, mean_speed_, pn, gain);
    const double pc_o =
        p_(o, kSpeedSqState) + h * (p_(o, kNoisePrev) - p_(o, kNoiseNow));  // (P Cᵀ)_o = K_o S
    out_var = p_(o, o) - gain(o) * pc_o;
    p_ = pn;
  }
  // (CK-11) split into measurement update and prediction: x̂_{k|k} = x̂_{k|k−1} + K (y − C x̂_{k|k−1}).
  last_innovation_ = y - x_(kSpeedSqState) - h * (x_(kNoisePrev) - x_(kNoiseNow));
  x_ += gain * last_innovation_;
  push_edge_time(s.t_ns);
  ++teeth_seen_;
  ++stats_.updates;
  // With APS gains P is only set at a (re)start (checked there): 64 checks per tooth were a third of
  // update().
  if (!params_.periodic_gains) p_finite_ = p_.allFinite();
  if (!all_finite(x_) || !p_finite_) {
    ++stats_.resets;
    reset();
    est_.health = Health::kNumerical;
    return false;
  }
  output_model_nm_ = model_[static_cast<std::size_t>(params_.smoother_lag)];
  est_.torque_nm = x_(o) + output_model_nm_ + load_star_nm_;
  est_.t_ns = edge_t_ns_[static_cast<std::size_t>(params_.smoother_lag)];
  est_.uncertainty = out_var > 0.0 ? std::sqrt(out_var) : 0.0;  // APS: 0 without a call
  est_tooth_ = k >= params_.smoother_lag ? k - params_.smoother_lag : k - params_.smoother_lag + kk;
  est_.health = (teeth_seen_ >= kk && wheel_learned_) ? Health::kValid : Health::kNotConverged;
  predict(k);
  expected_tooth_ = k + 1 == kk ? 0 : k + 1;
  return true;
}

}  // namespace torqued
