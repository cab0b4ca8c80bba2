#pragma once
// Per-cylinder indicated torque, imbalance and misfire per cycle (docs/equations.md §4, beyond the papers).
// Measure: the indicated work of each firing segment, W_m = Δ(½Jθ̇²)_segment + ∫(T_load + T_fric) dθ (energy
// balance, CycleEnergy). The segment of firing position m starts 20° before its TDC, so it holds cylinder m's
// whole combustion and expansion; the compression work it also holds belongs to the next cylinder and is the
// same for all cylinders (same MAP), so W_m − mean(W) is cylinder m's surplus. Cylinder m's share of the
// cycle-mean indicated torque is W_m / 4π (the shares add up to the cycle mean). This energy gain is robust
// at 4000 rpm where the speed dip of a misfire is small, because it integrates over the whole segment instead
// of looking at a speed minimum.
//   imbalance_m = (W_m − W̄) / max(W̄, W_floor) · 100 %, W̄ = mean_j W_j, W_floor = share_floor_imep_bar × swept
//                 volume of one cylinder: the usual (W_m/W̄ − 1) wherever the engine fires (idle is 1-2 bar
//                 net IMEP), bounded where the mean is small or negative (overrun, idle after a fuel cut-off)
//   filtered    = EMA of imbalance_m over usable cycles, weight min(imbalance_filter, 1 − exp(−T_cycle/τ)):
//   the
//                 same averaging time (imbalance_tau_s) at every speed; the mean of the k usable cycles so
//                 far while 1/k is larger (a start from one cycle kept that cycle's noise: 70 % of it after
//                 10 cycles at 6000 rpm); imbalance_sd_pct its 1σ from the running share noise
//   misfire_m   = C_m < threshold · median_{j≠m} C_j with the combustion work C = W − W_mot, decided only
//                 while the engine fires (no fuel cut-off) and the reference exceeds min_mean_nm
//                 (segment-mean torque), and the deficit med − C_m exceeds misfire_sigma × the running
//                 cycle-to-cycle noise of the shares (× the share scale)
//                 The reference is the running firing level L (EMA of the cycle's median combustion work
//                 over cycles decided without candidates) instead where the median of the others is
//                 itself below threshold · L while some segment of the cycle still fires at ≥ 0.8 L: two
//                 misfires in one cycle of an I3 (or three of an I6) pull the median down to a misfire's
//                 level. The same level keeps the low-load and noise gates from reading such a cycle as
//                 idle. The segment right after a decided misfire (the next firing position, across the
//                 cycle end too) misses the misfired cylinder's expansion tail (EVO 120-160° ATDC reaches
//                 into it): its threshold is misfire_threshold × misfire_after_factor
//   W_mot       = the motored level, a segment's work without combustion (pumping + compression loss, ≤ 0):
//                 the median segment work of steady fuel cut-off cycles, filtered; 0 until a cut-off was
//                 seen. At idle after a cut-off (closed throttle) the pumping loss makes a firing segment's
//                 net work W ≈ 0, so W < threshold·med cannot tell a misfire; C still carries the whole
//                 combustion. After a cut-off the caller's fired flags arm late (a flag leading the
//                 injections must not be a false alarm); a cycle in which every segment combusted shows the
//                 fuel is back, and from the next cycle on the misfire decision runs although the flags still
//                 say cut-off
// Where a misfire cannot be decided the record says why (`detection`), no misfire is flagged there (a
// decision where detection is not possible is a false alarm waiting to happen) and its health is
// not kValid: kNotExcited in overrun (no combustion to miss), below min_mean_nm and where the shares are too
// noisy (kNoisy: misfire_sigma·σ·scale ≥ (1 − misfire_threshold) × the firing level, so that a cylinder at
// the threshold would sit inside the noise and the decision would rest on the noise gate alone, which
// heavy-tailed jitter trips now and then; latched, left below 0.8 of that limit, noisy from the start on the
// prior σ), kNotConverged while the wheel's tooth table is unlearned (tooth errors bias each segment's work),
// kInvalidInput on bad segments. The filtered imbalance is updated only from cycles where detection is active
// or only the wheel is unlearned, and nothing misfired.
#include <array>
#include <cstdint>

#include "engine_geometry.hpp"
#include "estimate.hpp"
#include "params.hpp"

namespace torqued {

/// Expansion spill: the fraction of a cylinder's combustion work that its segment's end boundary hands to the
/// next segment (beyond the papers). Polytropic expansion (γ = 1.3, textbook) from the burn centroid
/// `centroid_atdc_deg` to the exhaust valve opening `evo_atdc_deg`, dW = p dV ∝ V^−γ dV (crank-slider
/// volume, the geometry's compression ratio), each angle's work attributed to the next segment by the share
/// of the boundary's kinetic-energy window (`window_deg` long, ending `window_after_deg` after the boundary,
/// weights 1 − taper·(2x − 1)²) that lies before it. `segment_end_atdc_deg`: the boundary after a cylinder's
/// TDC. 0 where the window starts after EVO (an I4's or I3's segments: 160°/220° ATDC); ≈ 0.1 on an I6's
/// 120° segments (boundary at 100° ATDC). Not real-time code (construction only).
[[nodiscard]] double expansion_spill(const EngineGeometry& engine, double segment_end_atdc_deg,
                                     double window_deg, double window_after_deg, double taper,
                                     double centroid_atdc_deg, double evo_atdc_deg) noexcept;

/// Why misfire detection is (not) active this cycle.
enum class MisfireDetection : std::uint8_t {
  kActive = 0,
  kOverrun = 1,  ///< fuel cut-off on some cylinder: nothing fires, nothing can misfire
  kLowLoad = 2,  ///< median segment-mean torque below min_mean_nm: a missing combustion is not told apart
  kWheelUnlearned = 3,  ///< tooth table not learned yet: the shares carry the wheel's bias, no decision
  kInvalid = 4,         ///< a segment was invalid (lost teeth, non-finite work)
  kNoisy = 5,  ///< the shares' cycle-to-cycle noise (high speed, light load: jitter over a small speed
               ///< ripple) is too large for the misfire threshold: no decision
};
[[nodiscard]] const char* to_string(MisfireDetection d) noexcept;

struct CylinderCycle {
  std::int64_t t_ns = 0;    ///< time of the tooth that completed the cycle (ns)
  std::uint32_t cycle = 0;  ///< cycles completed since reset
  int cylinders = 0;
  std::array<double, kMaxCylinders> torque_nm{};               ///< W_m / 4π by cylinder number − 1 (N m)
  std::array<double, kMaxCylinders> imbalance_pct{};           ///< this cycle (%)
  std::array<double, kMaxCylinders> imbalance_filtered_pct{};  ///< EMA over firing cycles without misfire (%)
  /// 1σ of imbalance_filtered_pct from the shares' cycle-to-cycle noise and the cycles averaged (pp, each
  /// cylinder; 0 before the first usable cycle). At 6000 rpm and light load the shares swing ≈ ±12 % per
  /// cycle (edge jitter over a small speed ripple): what the filtered pattern rests on.
  double imbalance_sd_pct = 0.0;
  std::array<bool, kMaxCylinders> misfire{};
  int misfire_count = 0;
  double mean_nm = 0.0;  ///< Σ torque_nm = cycle-mean indicated torque (N m)
  MisfireDetection detection = MisfireDetection::kInvalid;
  Health health = Health::kNotConverged;
};

class CylinderTorque {
 public:
  CylinderTorque(const EngineGeometry& engine, const CylinderParams& params) noexcept;
  void reset() noexcept;
  /// The segment of firing position `position` (0 = first in the firing order) ended with indicated work
  /// `work_j`. `fired`: fuel was injected (no fuel cut-off). Returns true when the last position of the cycle
  /// ended; then cycle() holds the record. Real-time safe.
  bool on_segment(std::int64_t t_ns, int position, double work_j, bool valid, bool fired) noexcept;
  [[nodiscard]] const CylinderCycle& cycle() const noexcept { return out_; }
  /// Whether the crank wheel's tooth table is learned (default true: a wheel without table is the caller's
  /// call).
  void set_wheel_learned(bool learned) noexcept { wheel_learned_ = learned; }
  [[nodiscard]] std::uint64_t misfires() const noexcept { return misfires_; }
  /// Expansion spill s (expansion_spill(), clamped to [0, 0.4]): the published filtered imbalance is the
  /// pattern of the cylinders' own work, d_m = (1 − s)·c_m + s·c_{m−1} (m in firing order) solved for c.
  /// A spill below 0.01 is taken as 0: it would move the pattern by under 1 % of a neighbour's deviation
  /// (0.1 pp next to a 10 % weak cylinder), below the pattern's noise (an I4's 160° boundary: 0.002).
  void set_spill(double s) noexcept {
    constexpr double kMinSpill = 0.01, kMaxSpill = 0.4;
    spill_ = s >= kMinSpill ? (s < kMaxSpill ? s : kMaxSpill) : 0.0;
  }
  [[nodiscard]] double spill() const noexcept { return spill_; }

 private:
  /// This cycle's segment sums (and comb_, each segment's work above the motored level).
  struct CycleSums {
    bool all_valid = true, all_fired = true, any_fired = false;
    double sum = 0.0;  ///< J
  };
  /// This cycle's scale of the shares, segment noise and firing level (J).
  struct CycleLevels {
    double mean_w = 0.0, scale = 0.0, sigma_j = 0.0, fired_level_j = 0.0;
    bool anchored = false;  ///< some segment fires at the running level L: L is a reference
  };
  CycleSums sum_cycle(int n) noexcept;
  [[nodiscard]] CycleLevels cycle_levels(int n, double mean_w) const noexcept;
  /// Per cylinder torque, share and misfire flag into `o`; returns the candidates (segments below the
  /// ordinary threshold, decided or not).
  int flag_misfires(CylinderCycle& o, const CycleLevels& lv, bool resumed) noexcept;
  /// The running firing level L from a clean decided cycle; forgotten in an overrun.
  void update_level(MisfireDetection detection, int candidates) noexcept;
  /// Motored level: learns the segment work of steady fuel cut-off cycles, tracks the resume after one.
  void track_overrun(bool all_fired, double median_work_j) noexcept;
  /// Every segment of this cycle carried a combustion (the whole cycle is above the motored level).
  [[nodiscard]] bool all_combusting(int n, double seg_rad) const noexcept;
  /// `cycle_dt_s`: duration of this cycle (s), 0 if unknown (the per-cycle weight alone).
  void update_filtered_imbalance(const CylinderCycle& o, int candidates, double cycle_dt_s) noexcept;
  /// Noise state from the segment noise σ (J) and the cycle's firing level (J); real-time safe.
  bool update_noisy(double sigma_j, double fired_level_j) noexcept;
  static Health health_of(MisfireDetection d) noexcept;
  /// Reference of position m: the median of the others, or L where that median is pulled down (see above).
  [[nodiscard]] double reference_j(int n, int m, bool anchored) const noexcept;
  EngineGeometry engine_;
  CylinderParams params_;
  std::array<double, kMaxCylinders> work_{};
  std::array<bool, kMaxCylinders> valid_{};
  std::array<bool, kMaxCylinders> fired_{};
  std::array<double, kMaxCylinders> comb_{};  ///< this cycle's combustion work W_m − W_mot (J)
  std::array<double, kMaxCylinders> ema_{};
  bool ema_init_ = false;
  int ema_cycles_ = 0;    ///< usable cycles averaged so far (the mean of all of them until the EMA's weight)
  double ema_var_ = 0.0;  ///< variance of ema_ from the share noise (fraction²)
  double share_var_ =
      0.0;             ///< EMA of the squared cycle-to-cycle share noise (fraction², pooled over cylinders)
  bool noisy_ = true;  ///< the shares too noisy to decide (latched, see on_segment)
  bool wheel_learned_ = true;
  double motored_j_ = 0.0;  ///< W_mot: segment work without combustion (J, ≤ 0), from steady cut-off cycles
  bool motored_known_ = false;  ///< W_mot measured (else 0)
  int cut_cycles_ = 0;          ///< consecutive cycles with no segment flagged fired
  bool after_cut_ = false;      ///< a steady cut-off was seen and no cycle since was flagged fired throughout
  bool prev_combusting_ = false;
  double level_j_ = 0.0;            ///< L: running firing level, median combustion work of clean cycles (J)
  bool level_known_ = false;        ///< L measured
  bool prev_last_misfire_ = false;  ///< the last firing position of the previous cycle was a misfire  ///<
                                    ///< the previous cycle combusted in every segment (all_combusting)
  double w_floor_j_ = 0.0;          ///< share floor (J)
  double spill_ = 0.0;              ///< expansion spill s (set_spill)
  /// The filtered pattern of the cylinders' own work: ema_ with the spill taken out (real-time safe).
  [[nodiscard]] std::array<double, kMaxCylinders> despilled() const noexcept;
  std::uint32_t cycles_ = 0;
  std::int64_t prev_cycle_t_ns_ = 0;  ///< time of the previous cycle's end (ns), 0 before the first
  std::uint64_t misfires_ = 0;
  CylinderCycle out_;
};

}  // namespace torqued
