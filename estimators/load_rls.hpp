#pragma once
// Load torque by recursive least squares in the compression window (Energies 2019 eq. (EN-10)..(EN-15)).
//
// In the window 50°..20° before each firing TDC no cylinder burns, so the crank balance holds with a gas torque
// computed from a pressure model alone:  T_u = T_gas − T_r = J_e θ̈ + T_load*  (EN-10/11), T_load* = T_load + T_fric
// (the "extended load"), regressed on [θ̈, 1] by RLS and carried from cycle to cycle (EN-13..15).
//
// Two deliberate departures from the paper, both to remove biases a physics simulator exposes:
//  1. Energy form. Per window [c_a, c_b] (centres of its first and last tooth period) the balance is integrated:
//       y = (∫T_gas dθ − Δ[½(J(θ) − J_rot) θ̇²]) / Δθ = J_e · Δ(½θ̇²)/Δθ + T_load*
//     Δ(½θ̇²)/Δθ is the angle-mean θ̈: no numerical second derivative, no ½J'θ̇² term, exact for a rigid crank.
//     By default J_e is the known J_rot (rls_estimate_inertia = false): in steady operation θ̈ hardly varies between
//     windows, so the 2-parameter regression is poorly excited and its J_e drifts; the paper's form is an option.
//  2. The cylinder that fired one segment earlier is NOT at zero gas torque: in a 4-cylinder engine it is 130°-160°
//     after its TDC, between exhaust-valve opening and the end of blowdown, and its pressure is several bar
//     (ignoring it biases T_load* by 10-20 N m). Every cylinder gets a full-cycle pressure model:
//       [0, EVO)            polytropic expansion  p3 (V_c/V)^κ
//       [EVO, blowdown end) raised-cosine blend from that expansion to p_exh (blowdown)
//       [.., 360°)          p_exh;  [360°, BDC + IVC) intake at MAP;  [IVC, 720°) polytropic compression from
//                           p_IVC = factor · MAP (EN-7)
//     p3 is found "from the observed cycle": the cycle's indicated work of that cylinder W_j (energy balance of its
//     segment, CylinderTorque) closes the cycle integral ∮p dV = W_j, which is linear in p3. Without a measured W_j
//     the cylinder is assumed motored. The heat release is lumped at a burn centroid (default 8° ATDC, a typical
//     50 %-burned angle = spark + burn_delay_deg, with the spark advance from CAN) rather than at TDC, which would
//     understate the late expansion pressure for a given work. Checked against the simulator's single-zone
//     Wiebe pressure trace in test_load_rls.
//  3. Each window is repeated shifted by 1..rls_window_shifts−1 teeth earlier: averaging the shifted windows
//     averages θ̇² over consecutive teeth at both ends, whose timestamp jitter telescopes (noise ÷ shifts). All window integrals are linear in (MAP, p3_j, p_exh, p_cc) and are
//     precomputed at construction, so the per-tooth cost is a few multiply-adds.
#include <array>
#include <cstdint>
#include <vector>

#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "params.hpp"
#include "samples.hpp"

namespace torqued {

class LoadRls {
 public:
  LoadRls(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params);
  void reset() noexcept;

  /// Real-time safe. `cyl_work_j[position]`: last measured indicated work per cycle of each firing position (J),
  /// `works_valid`: use them for the expansion pressure (else motored). Returns true when a window completed and
  /// the estimate was updated.
  /// `spark_advance_deg`: NaN when unknown (then burn_centroid_atdc_deg is used).
  bool update(const ToothSample& s, double map_pa, bool map_valid, double spark_advance_deg,
              const std::array<double, kMaxCylinders>& cyl_work_j, bool works_valid) noexcept;

  /// Extended load T_load + T_fric (N m); uncertainty = 1σ of the mean from the residuals.
  [[nodiscard]] TorqueEstimate estimate() const noexcept { return est_; }
  [[nodiscard]] double inertia_estimate() const noexcept { return theta_[0]; }
  [[nodiscard]] std::uint64_t windows() const noexcept { return windows_; }
  /// Last window's observation y (N m) and mean acceleration regressor (rad/s²) (diagnostics, tests).
  [[nodiscard]] double last_y() const noexcept { return last_y_; }
  /// Gas work over window `w` (J) for the given pressures; exposed for tests of the pressure model.
  [[nodiscard]] double window_gas_work(int w, double map_pa, const std::array<double, kMaxCylinders>& p3_pa) const noexcept;
  /// p3 (Pa) that closes ∮p dV = work_j for one cylinder at this MAP and spark advance (NaN: unknown).
  [[nodiscard]] double expansion_p3(double work_j, double map_pa, double spark_advance_deg) const noexcept;
  /// Burn centroid (deg ATDC) used for a spark advance (NaN: unknown).
  [[nodiscard]] double centroid_deg(double spark_advance_deg) const noexcept;
  /// Modelled cylinder pressure (Pa) at `local_rad` after that cylinder's firing TDC (tests, diagnostics).
  [[nodiscard]] double model_pressure(double local_rad, double map_pa, double p3_pa,
                                      double spark_advance_deg) const noexcept;
  /// p3 of a motored cylinder (no combustion) at this MAP.
  [[nodiscard]] double motored_p3(double map_pa) const noexcept;
  /// Cycle-mean indicated torque of the whole engine when motored (fuel cut-off) at this MAP: the pumping loop and
  /// the expansion lost at EVO (N m, negative). Used to turn a fuel cut-off energy balance into friction.
  [[nodiscard]] double motored_torque_nm(double map_pa) const noexcept;

 private:
  struct Window {
    int first = 0, last = 0;       ///< tooth indices (sequence order)
    double c_first = 0.0, c_last = 0.0, span = 0.0;  ///< centres relative to cyl-1 TDC (rad), span (rad)
    double j_first = 0.0, j_last = 0.0;
    double k_map = 0.0, k_exh = 0.0, k_cc = 0.0;     ///< gas work per Pa of MAP, p_exh, p_cc (m³)
    std::array<double, kMaxCylinders> k_p3{};        ///< per firing position: gas work per Pa of p3 (m³)
  };
  EngineGeometry engine_;
  EnergiesParams params_;
  int samples_ = 0;
  std::vector<Window> windows_tab_;
  std::vector<int> window_first_of_;  ///< window index opened by tooth k, −1 if none
  std::vector<int> window_last_of_;   ///< window index closed by tooth k, −1 if none
  static constexpr int kCentroids = 61;  ///< closure tables for burn centroids 0..60° ATDC
  std::array<double, kCentroids> cyc_map_{}, cyc_p3_{};  ///< full-cycle ∮p dV coefficients of one cylinder (m³)
  double cyc_exh_ = 0.0;
  double v_ivc_ = 0.0, v_c_ = 0.0;
  double kappa_ = 1.3;

  std::vector<std::uint8_t> open_;   ///< per window: first tooth seen, last not yet
  std::vector<double> ke_first_, w2_first_;
  int expected_tooth_ = -1;
  std::array<double, 2> theta_{};   ///< [J_e, T_load*]
  std::array<double, 4> p_{};       ///< RLS covariance (2x2, row-major)
  double resid_var_ = 0.0;
  double last_y_ = 0.0;
  std::uint64_t windows_ = 0;
  TorqueEstimate est_;
};

}  // namespace torqued
