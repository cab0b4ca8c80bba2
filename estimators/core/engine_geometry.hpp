#pragma once
// Engine and crank-wheel geometry shared by the estimators, the simulator and the decoder.
// Pure data; validated by the config loader (config/), never clamped here.
#include <array>
#include <cstdint>

namespace torqued {

inline constexpr int kMaxCylinders = 8;
inline constexpr int kMaxTeeth = 360;  ///< upper bound on physical tooth positions of a wheel

/// Slider-crank engine description (docs/equations.md §0). SI units throughout.
struct EngineGeometry {
  int cylinders = 4;  ///< number of cylinders (4-stroke)
  std::array<int, kMaxCylinders> firing_order{1, 3, 4,
                                              2};  ///< 1-based cylinder numbers, first `cylinders` used
  double bore_m = 0.0825;                          ///< bore (m)
  double stroke_m = 0.0860;                        ///< stroke (m) = 2R
  double rod_m = 0.1450;                           ///< connecting-rod length l (m)
  double compression_ratio = 10.5;                 ///< r_c (-): a spec-sheet value the configuration gives
                                                   ///< (engine.compression_ratio); 10.5 is only a typical
                                                   ///< port-injected gasoline engine's, not a tuning value:
                                                   ///< geometry (physics). The simulator's demo engine shares
                                                   ///< this struct; every estimator gets r_c from the config
                                                   ///< (the bed's engines draw 9.5-12 and write it there)
  double j_rot_kgm2 = 0.16;                        ///< rotating inertia incl. flywheel and dyno side (kg m^2)
  double m_osc_kg = 0.55;                          ///< oscillating mass per cylinder (piston + 1/3 rod) (kg)
  double tdc_offset_rad =
      1.5707963267948966;  ///< crank angle of cyl-1 firing TDC after first tooth after gap (rad)
  double crankcase_pressure_pa = 101325.0;  ///< p_crankcase (Pa)

  [[nodiscard]] double crank_radius_m() const noexcept { return 0.5 * stroke_m; }
};

/// Crank wheel: N equally spaced positions with M of them missing, or an explicit tooth-angle list.
struct WheelGeometry {
  int positions =
      60;           ///< equally spaced tooth positions per revolution incl. missing ones (e.g. 60 for 60-2)
  int missing = 2;  ///< missing teeth in the (single) gap, for N-M wheels
  int tooth_count = 0;  ///< real teeth when `tooth_angles_deg` is used (0: N-M wheel)
  std::array<double, kMaxTeeth> tooth_angles_deg{};  ///< explicit edge angles in [0,360) (irregular wheels)
  bool rising_edge = true;                           ///< which edge of the crank channel marks a tooth

  [[nodiscard]] int teeth() const noexcept { return tooth_count > 0 ? tooth_count : positions - missing; }
};

}  // namespace torqued
