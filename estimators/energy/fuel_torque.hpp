#pragma once
// Fuel-based indicated torque with a learned efficiency (docs/equations.md §5, the fuel model): the vehicle
// has no load-torque signal, but the ECU reports the injected fuel mass on CAN. Willans-line reasoning
// (Heywood 1988, ch. 13; EN-16 without the efficiency map): the net indicated torque of a 4-stroke SI engine
// per cycle is
//   T_ind = η_g · n_cyl m_f q_LHV / 4π  −  (p_exh − p_man) V_d / 4π
//           [gross indicated work]          [pumping loop, ≈ (exhaust − intake pressure) × swept volume]
// with η_g (gross indicated efficiency) and p_exh unknown on an unseen engine. Both are learned by a
// 2-parameter RLS (forgetting) on y = T_ind,ref − p_man V_d/4π against φ = [F, −V_d/4π] (F = n_cyl m_f q_LHV
// / 4π) whenever a reference is present: T_ind,ref = energy-balance brake torque with the measured load +
// learned friction. Priors: η_g = 0.38 (typical gross indicated fuel conversion efficiency of a warm SI
// engine at λ = 1, Heywood fig. 13-9 order of magnitude), p_exh = 105 kPa (ambient + a few kPa of exhaust
// back-pressure); both with wide priors. The claimed 1σ is measured, not assumed: the 68th percentile of
// |reference residual| once valid (CoverageScale: the residuals are heavy-tailed across operating points, so
// their RMS was covered 80-100 % of the time), with the parameter uncertainty at the operating point.
// Real-time safe: no allocation, no exceptions.
#include <array>
#include <cstdint>

#include "coverage_scale.hpp"
#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "fuel_angle_window.hpp"

namespace torqued {

struct FuelTorqueParams {
  double eta_prior = 0.38;             ///< gross indicated efficiency prior (-)
  double eta_prior_sd = 0.10;          ///< its 1σ (-)
  double p_exh_prior_pa = 105000.0;    ///< exhaust pressure prior (Pa): physics (ambient + a typical exhaust
                                       ///< system drop), learned while a torque reference is present
  double p_exh_prior_sd_pa = 15000.0;  ///< its 1σ (Pa)
  double forgetting = 0.999;           ///< RLS forgetting per reference cycle (-)
  double residual_sd_nm = 2.0;         ///< measurement 1σ of one reference cycle (N m)
  int min_references = 30;             ///< reference cycles before the estimate is valid (-)
  double sd_ema =
      0.005;  ///< residual variance: EMA weight before valid, floor of the running-mean weight 1/k after (-)
  double fuel_lhv_j_kg = 43e6;  ///< q_LHV (J/kg)
  // The angle window (FuelAngleWindow): which intake events' fuel and MAP a 720° window's work comes from.
  double intake_btdc_deg = 130.0;  ///< intake event (IVC, fuel decided) before firing TDC (deg): IVC 40-60°
                                   ///< after BDC (Heywood 1988 §6.3)
  double work_centroid_atdc_deg = 160.0;  ///< centroid of a cylinder's work after its firing TDC (deg);
                                          ///< chosen on the unseen bed's TUNING engines only
  double report_window_s =
      0.010;  ///< an intake event's cut-off state is revised by consistent CAN reports for this
              ///< long after it (s): one period of a 100 Hz ECU frame (the CAN frame seen at
              ///< the intake can be that much older than the injection decision)
  double transient_sd_scale =
      0.25;  ///< claimed 1σ added per N m of model-torque spread across the window (-)
  double sd_floor_nm = 0.1;  ///< the coverage-calibrated residual scale never claims less (N m)
};

/// Learned state (persisted with the friction coefficients).
struct FuelTorqueState {
  std::array<double, 2> theta{};  ///< [η_g, p_exh V_d/4π (N m)]
  std::array<double, 4> p{};      ///< RLS covariance (row-major 2x2)
  double resid_var = 0.0;         ///< residual variance (N m²): the outlier gate's scale
  std::uint32_t references = 0;
  CoverageScale cover;  ///< 68th percentile of |residual| once valid (N m), sd 0: not yet
};

class FuelTorque {
 public:
  FuelTorque(const EngineGeometry& engine, const FuelTorqueParams& params) noexcept;
  void reset() noexcept;
  /// Indicated torque (N m) from the fuel per injection per cylinder (kg) and the manifold pressure (Pa).
  [[nodiscard]] TorqueEstimate estimate(std::int64_t t_ns, double fuel_kg, double map_pa) const noexcept;
  /// Indicated torque of a 720° window (FuelAngleWindow): its fired events by the fuel model, its cut-off
  /// events by `motored` (no combustion; the fuel model at zero fuel when `motored` is not valid), weighted
  /// by their count. The claimed 1σ grows with the spread of the model torque across the window's events
  /// (transients, cut-off entry/exit: the work near the window's edges is attributed to one event or its
  /// neighbour).
  [[nodiscard]] TorqueEstimate estimate_window(std::int64_t t_ns, const FuelWindow& w,
                                               const TorqueEstimate& motored) const noexcept;
  /// One reference cycle: true indicated torque `t_ind_ref` (N m) at that fuel and MAP. Rejects non-finite
  /// input and residuals beyond 5σ once valid (outliers). Returns true when learned from.
  bool learn(double fuel_kg, double map_pa, double t_ind_ref) noexcept;
  [[nodiscard]] const FuelTorqueState& state() const noexcept { return st_; }
  bool import_state(const FuelTorqueState& s) noexcept;
  [[nodiscard]] bool valid() const noexcept {
    return st_.references >= static_cast<std::uint32_t>(params_.min_references);
  }

 private:
  void observe_coverage(double err) noexcept;
  FuelTorqueParams params_;
  int n_cyl_;
  double vd_4pi_;  ///< V_d / 4π (m³/rad)
  FuelTorqueState st_;
};

}  // namespace torqued
