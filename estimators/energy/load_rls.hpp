#pragma once
// Load torque by recursive least squares in the compression window (Energies 2019 eq. (EN-10)..(EN-15)).
//
// In the window 50°..20° before each firing TDC no cylinder burns, so the crank balance holds with a gas
// torque computed from a pressure model alone:  T_u = T_gas − T_r = J_e θ̈ + T_load*  (EN-10/11), T_load* =
// T_load + T_fric (the "extended load"), regressed on [θ̈, 1] by RLS and carried from cycle to cycle
// (EN-13..15).
//
// Two deliberate departures from the paper, both to remove biases a physics simulator exposes:
//  1. Energy form. Per window [c_a, c_b] (centres of its first and last tooth period) the balance is
//  integrated:
//       y = (∫T_gas dθ − Δ[½(J(θ) − J_rot) θ̇²]) / Δθ = J_e · Δ(½θ̇²)/Δθ + T_load*
//     Δ(½θ̇²)/Δθ is the angle-mean θ̈: no numerical second derivative, no ½J'θ̇² term, exact for a rigid crank.
//     By default J_e is the known J_rot (rls_estimate_inertia = false): in steady operation θ̈ hardly varies
//     between windows, so the 2-parameter regression is poorly excited and its J_e drifts; the paper's form
//     is an option.
//  2. The cylinder that fired one segment earlier is NOT at zero gas torque: in a 4-cylinder engine it is
//  130°-160°
//     after its TDC, between exhaust-valve opening and the end of blowdown, and its pressure is several bar
//     (ignoring it biases T_load* by 10-20 N m). Every cylinder gets a full-cycle pressure model:
//       [0, EVO)            polytropic expansion  p3 (V_c/V)^κ
//       [EVO, blowdown end) raised-cosine blend from that expansion to p_exh (blowdown)
//       [.., 360°)          p_exh;  [360°, BDC + IVC) intake at MAP;  [IVC, 720°) polytropic compression from
//                           p_IVC = factor · MAP (EN-7)
//     p3 is found "from the observed cycle": the cycle's indicated work of that cylinder W_j (energy balance
//     of its segment, CylinderTorque) closes the cycle integral ∮p dV = W_j, which is linear in p3. Without a
//     measured W_j the cylinder is assumed motored. The heat release is lumped at a burn centroid (default 8°
//     ATDC, a typical 50 %-burned angle = spark + burn_delay_deg, with the spark advance from CAN) rather
//     than at TDC, which would understate the late expansion pressure for a given work. Checked against the
//     simulator's single-zone Wiebe pressure trace in test_load_rls.
//  4. Transients (a filter with a zero-mean torque model under-reads sustained changes). The RLS average
//     over ~10 cycles is the low-noise value in steady state but lags a load step or a dyno ramp by 10-30
//     cycles. The observations of one 720° window (every firing's compression window, all shifts) are
//     themselves an unbiased measure of the mean load over that window (±2 N m at 2000 rpm: the shifted
//     windows telescope), so a cycle mean z is formed once per firing from the per-firing means h_0 (newest)
//     .. h_n with trapezoid weights (½h_0 + h_1 + … + h_{n−1} + ½h_n)/n, centred on the same 720° as the
//     crank energy balance. A load change is detected by a two-sided CUSUM (Page 1954) of the per-firing
//     innovations e = h − RLS in units of their steady 1σ (allowance 0.5σ, threshold rls_change_threshold),
//     confirmed by |z − RLS| > 2.5σ of its own steady spread (z − RLS is correlated from firing to firing,
//     which alone would let the CUSUM fire on noise): a tracker copy of the RLS is re-seeded at z (its memory
//     restarts, so it re-converges on the new load instead of averaging the old one) and z is reported for
//     one cycle (tracked()); its memory is held at one cycle for 4 more cycles (the load keeps settling). The
//     plain RLS (estimate()) is left alone for the friction learning at idle. z is noisy (≈ ±2-4 N m at 2000
//     rpm, ±10-20 N m at 4000 rpm from the timestamp jitter): in steady operation the RLS average stays the
//     output, a false alarm costs one cycle of z noise, and no change is tracked while the steady spread of z
//     exceeds rls_change_max_sd_nm (there the RLS average is the better value even in transients). The
//     crank-only brake = Δ(½Jθ̇²)/4π + this extended load − friction is then an energy balance over each cycle
//     with a measured (not predicted) load term.
//  3. Each window is repeated shifted by 1..rls_window_shifts−1 teeth earlier: averaging the shifted windows
//     averages θ̇² over consecutive teeth at both ends, whose timestamp jitter telescopes (noise ÷ shifts).
//     All window integrals are linear in (MAP, p3_j, p_exh, p_cc) and are precomputed at construction, so the
//     per-tooth cost is a few multiply-adds.
#include <array>
#include <cstdint>
#include <vector>

#include "crank_kinematics.hpp"
#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "params.hpp"
#include "samples.hpp"

namespace torqued {

class LoadRls {
 public:
  /// `spark_on_can`: a spark advance can arrive (the configuration maps its CAN signal). Without one, or
  /// with energies.incycle_spark_phasing off, the in-cycle model's burn centroid stays fixed and only the
  /// ripple tables it can read are built (ripple_first(), ripple_last()).
  LoadRls(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params,
          bool spark_on_can = true);
  void reset() noexcept;

  /// Real-time safe. `cyl_work_j[position]`: last measured indicated work per cycle of each firing position
  /// (J), `works_valid`: use them for the expansion pressure (else motored). Returns true when a window
  /// completed and the estimate was updated. `spark_advance_deg`: NaN when unknown (then
  /// burn_centroid_atdc_deg is used).
  bool update(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
              const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept;
  /// update() for a sample already checked as update() does (synced, positive dt and width, tooth in
  /// [0, samples)): AnglePipeline::on_tooth checks once per tooth. Real-time safe.
  bool update_checked(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
                      const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept;

  /// Extended load T_load + T_fric (N m) from the RLS (EN-15); uncertainty = 1σ of the mean from the
  /// residuals.
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return est_; }
  /// The same load tracked through transients (rule 4): a second RLS on the same observations, re-seeded at
  /// the cycle mean when a load change is detected, and the cycle mean itself for one cycle after it. For the
  /// crank-only brake torque; estimate() stays the plain RLS (idle friction learning, in-cycle observers).
  [[nodiscard]] TorqueEstimate tracked() const noexcept { return trk_; }
  /// Trapezoid cycle mean z of the last 720° of observations (N m).
  [[nodiscard]] double cycle_mean_nm() const noexcept { return z_cycle_; }
  /// Load changes detected (tracker re-seeded) since reset.
  [[nodiscard]] std::uint64_t load_changes() const noexcept { return load_changes_; }
  [[nodiscard]] double inertia_estimate() const noexcept { return theta_[0]; }
  [[nodiscard]] std::uint64_t windows() const noexcept { return windows_; }
  /// Last window's observation y (N m) and mean acceleration regressor (rad/s²) (diagnostics, tests).
  [[nodiscard]] double last_y() const noexcept { return last_y_; }
  /// Last window's extended-load observation y − J_e·θ̈ (N m): one noisy sample of T_load* in that window.
  [[nodiscard]] double last_observation_nm() const noexcept { return last_obs_; }
  /// Gas work over window `w` (J) for the given pressures; exposed for tests of the pressure model.
  [[nodiscard]] double window_gas_work(int w, double map_pa,
                                       const std::array<double, kMaxCylinders>& p3_pa) const noexcept;
  /// p3 (Pa) that closes ∮p dV = work_j for one cylinder at this MAP and spark advance (NaN: unknown).
  [[nodiscard]] double expansion_p3(double work_j, double map_pa, double spark_advance_deg) const noexcept;
  /// Burn centroid (deg ATDC) used for a spark advance (NaN: unknown).
  [[nodiscard]] double centroid_deg(double spark_advance_deg) const noexcept;
  /// Modelled cylinder pressure (Pa) at `local_rad` after that cylinder's firing TDC (tests, diagnostics).
  [[nodiscard]] double model_pressure(double local_rad, double map_pa, double p3_pa,
                                      double spark_advance_deg) const noexcept;
  /// p3 of a motored cylinder (no combustion) at this MAP.
  [[nodiscard]] double motored_p3(double map_pa) const noexcept;
  /// The in-cycle gas torque model is tabulated for kRippleTables burn centroids, kRippleStepDeg apart, table
  /// kRippleBase at energies.burn_centroid_atdc_deg (the fixed centroid, exact); ripple_table() picks the
  /// pair around a centroid (deg ATDC): table `t` and t + 1 with weight `frac` on t + 1.
  static constexpr int kRippleTables = 23;
  static constexpr int kRippleBase = 8;
  static constexpr double kRippleStepDeg = 2.0;
  void ripple_table(double centroid_deg, int& t, double& frac) const noexcept;
  /// The ripple tables built, [first, last]: the ones a centroid in energies.burn_centroid_atdc_deg's clamp
  /// range (0..60°, or that centroid alone without a spark advance or spark phasing) can read, and the base
  /// table. The others are zero (never read).
  [[nodiscard]] int ripple_first() const noexcept { return rip_lo_; }
  [[nodiscard]] int ripple_last() const noexcept { return rip_hi_; }
  /// The model's p3 per firing position for the in-cycle gas torque ripple of table `t`: closes the ripple
  /// model's ∮p dV on the measured works (energies.burn_duration_deg) when `works_valid`, else motored.
  void ripple_p3(double map_pa, const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid,
                 std::array<double, kMaxCylinders>& p3_pa, int t = kRippleBase) const noexcept;
  /// Gas torque of the pressure model (table `t`) over sample k's step [c_k, c_{k+1}] (the step
  /// ChauvinKalman integrates across edge k) minus its 720° mean (N m): the known shape of the in-cycle
  /// torque. Real-time safe.
  [[nodiscard]] double gas_ripple_nm(int k, double map_pa, const std::array<double, kMaxCylinders>& p3_pa,
                                     int t = kRippleBase) const noexcept;
  /// Cycle-mean indicated torque of the whole engine when motored (fuel cut-off) at this MAP: the pumping
  /// loop and the expansion lost at EVO (N m, negative). Used to turn a fuel cut-off energy balance into
  /// friction.
  [[nodiscard]] double motored_torque_nm(double map_pa) const noexcept;

 private:
  void restart(int expected_tooth) noexcept;
  struct Window {
    int first = 0, last = 0;                         ///< tooth indices (sequence order)
    double c_first = 0.0, c_last = 0.0, span = 0.0;  ///< centres relative to cyl-1 TDC (rad), span (rad)
    double j_first = 0.0, j_last = 0.0;
    double k_map = 0.0, k_exh = 0.0, k_cc = 0.0;  ///< gas work per Pa of MAP, p_exh, p_cc (m³)
    std::array<double, kMaxCylinders> k_p3{};     ///< per firing position: gas work per Pa of p3 (m³)
    int position = 0;                             ///< firing position whose compression it covers
    bool closes_group = false;                    ///< last window of that firing to close (smallest shift)
  };
  /// What every ripple table is built with: its burn centroid and burn start (rad), the burn duration (rad).
  struct RippleBuild {
    std::array<double, kRippleTables> burn{}, start{};
    double dur = 0.0;
    /// Below `full_below` (rad), or with s (φ − 4π beyond 2π) in (s_lo, s_hi), some table built reads the
    /// volume powers between the blowdown end and IVC (the centroid's compression, the burn).
    double full_below = 0.0, s_lo = 0.0, s_hi = 0.0;
  };
  void ripple_range(bool spark_on_can) noexcept;
  /// The table pair for a centroid (deg ATDC) among tables lo..hi (ripple_table() with the built ones).
  void table_pair(double centroid_deg, int lo, int hi, int& t, double& frac) const noexcept;
  void build_ripple(const std::vector<double>& center);
  void build_ripple_closure(const RippleBuild& b);
  void build_ripple_samples(const std::vector<double>& center, const RippleBuild& b);
  void build_tables(const CrankKinematics& kin, const std::vector<double>& center);
  void build_closure(const CrankKinematics& kin, double step);
  void build_windows(const CrankKinematics& kin, const std::vector<double>& center, double step);
  [[nodiscard]] std::uint64_t tables_key(const std::vector<double>& center) const noexcept;
  void pack_tables(std::vector<double>& t) const;
  bool unpack_tables(const std::vector<double>& t);  ///< false (nothing usable) on a size mismatch
  double rls_step(double y, double phi_a) noexcept;
  void publish(std::int64_t t_ns, double err, const Window& win) noexcept;
  void track(double obs, const Window& win) noexcept;
  EngineGeometry engine_;
  EnergiesParams params_;
  int samples_ = 0;
  std::vector<Window> windows_tab_;
  std::vector<int> window_first_of_;     ///< window index opened by tooth k, −1 if none
  std::vector<int> window_last_of_;      ///< window index closed by tooth k, −1 if none
  static constexpr int kCentroids = 61;  ///< closure tables for burn centroids 0..60° ATDC
  std::array<double, kCentroids> cyc_map_{},
      cyc_p3_{};  ///< full-cycle ∮p dV coefficients of one cylinder (m³)
  double cyc_exh_ = 0.0;
  /// gas_ripple_nm() per table and sample: torque per Pa of MAP ([t * samples + k]), of p3 per position
  /// ([(t * samples + k) * kMaxCylinders + q]), the constant p_exh / p_cc part (N m), each minus its 720°
  /// mean.
  std::vector<double> rip_map_, rip_p3_, rip_const_;
  /// The ripple model's full-cycle closure per table (m³, m³, J).
  std::array<double, kRippleTables> rip_cm_{}, rip_cp_{}, rip_ce_{};
  int rip_lo_ = 0, rip_hi_ = kRippleTables - 1;  ///< the ripple tables built (ripple_first/last)
  double v_ivc_ = 0.0, v_c_ = 0.0;
  double rip_motored_ = 0.0;  ///< (V_IVC/V_c)^κ of the ripple model's compression: its motored p3 / p_IVC
  double kappa_ = 1.3;

  std::vector<std::uint8_t> open_;  ///< per window: first tooth seen, last not yet
  std::vector<double> ke_first_, w2_first_;
  int expected_tooth_ = -1;
  std::array<double, 2> theta_{};  ///< [J_e, T_load*]
  std::array<double, 4> p_{};      ///< RLS covariance (2x2, row-major)
  double resid_var_ = 0.0;
  double last_y_ = 0.0;
  double last_obs_ = 0.0;
  // Transient tracker (rule 4).
  std::array<double, kMaxCylinders> grp_sum_{};
  std::array<int, kMaxCylinders> grp_n_{};
  std::array<double, kMaxCylinders + 1>
      hist_{};  ///< per-firing observation means, ring (newest at hist_head_)
  int hist_head_ = 0, hist_count_ = 0;
  double z_cycle_ = 0.0;
  bool z_valid_ = false;
  double d_var_ = 0.0;   ///< running variance of h − RLS in steady operation (N m²)
  double zd_var_ = 0.0;  ///< running variance of z − tracker in steady operation (N m²)
  int d_n_ = 0;
  double blend_ = 0.0;                        ///< weight of z in the output (0: RLS, 1: cycle mean)
  int hold_groups_ = 0;                       ///< firings left with the output on z after a load change
  double cusum_pos_ = 0.0, cusum_neg_ = 0.0;  ///< CUSUM of the per-firing innovations (σ units)
  std::uint64_t load_changes_ = 0;
  double trk_theta_ = 0.0, trk_p_ = 1e6;  ///< tracker RLS state (scalar, known J)
  int fast_windows_ = 0;                  ///< windows left with the tracker memory held at one cycle
  TorqueEstimate trk_;
  std::uint64_t windows_ = 0;
  TorqueEstimate est_;
};

// Per tooth: inline in the pipeline.
inline double LoadRls::gas_ripple_nm(int k, double map_pa, const std::array<double, kMaxCylinders>& p3_pa,
                                     int t) const noexcept {
  if (k < 0 || k >= samples_ || t < 0 || t >= kRippleTables) return 0.0;
  const auto kk =
      static_cast<std::size_t>(t) * static_cast<std::size_t>(samples_) + static_cast<std::size_t>(k);
  double v = rip_map_[kk] * map_pa + rip_const_[kk];
  for (int q = 0; q < engine_.cylinders; ++q)
    v += rip_p3_[kk * kMaxCylinders + static_cast<std::size_t>(q)] * p3_pa[static_cast<std::size_t>(q)];
  return v;
}

}  // namespace torqued
