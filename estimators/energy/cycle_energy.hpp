#pragma once
// Kinetic-energy balance per combustion segment and per 720° cycle (docs/equations.md §0 energy form, CF-2):
//   ½J(θ_b)θ̇_b² − ½J(θ_a)θ̇_a² = ∫_a^b (T_ind − T_fric − T_load) dθ
// so the angle-mean indicated torque over [a, b] is ΔKE/(b − a) + mean(T_load + T_fric). Unlike a Kalman
// filter whose torque model is zero-mean coloured noise, this has no bias during speed ramps.
//
// Boundaries: one per firing cylinder, at each firing TDC + `segment_offset_deg` (default 20° before TDC so
// that a cylinder's whole combustion lies inside "its" segment; compression work, equal for all cylinders,
// falls in the previous one). The kinetic energy at a boundary is the angle-weighted mean of
// ½J(c_k)(w_k/dt_k)² over the tooth periods whose centre c_k lies within ±energy_window/2 of it: the
// timestamp jitter and the machining error of the interior edges cancel (the sum telescopes), only the two
// outer edges remain, divided by the window width. The mean over a window equals the exact balance averaged
// over boundary shifts within the window, so it stays unbiased.
//
// CAN load latency (EnergiesParams::can_load_latency_s = τ). The measured load reaches us τ late
// (torque-flange lag + the sample-and-hold of a 100 Hz CAN frame: ≈ 5 ms + 5 ms on the bench/simulator): the
// value seen at time t is the flange torque of t − τ. The balance pairs ΔKE over [t_a, t_b] with the load
// over the same interval, so each tooth period's load is taken τ after the tooth (a delay line of pending
// teeth, filled in when the load of their time has arrived). At a segment end the teeth of its last τ are
// still pending; they get the newest load (hold extrapolation). On a load ramp r the cycle-mean error drops
// from r·τ to r·τ²/(2·T_seg) while τ < T_seg (segment duration; r·(τ − T_seg/2) above, e.g. 4000 rpm); a load
// step is booked in the segment where the flange saw it. The load of a segment therefore stays in its own
// segment: per-cylinder works and the ESO get the same alignment.
//
// Real-time safe update(); tables built at construction.
#include <array>
#include <cstdint>
#include <vector>

#include "crank_kinematics.hpp"
#include "engine_geometry.hpp"
#include "params.hpp"
#include "samples.hpp"

namespace torqued {

/// Nominal edge angles of one revolution (rad, tooth 0 = first after the gap at 0) and the widths of the
/// periods ending at them: N−M wheel or explicit `tooth_angles_deg`. Construction-time helper (allocates).
void nominal_wheel_edges(const WheelGeometry& wheel, std::vector<double>& edge_rad,
                         std::vector<double>& width_rad);

/// What CycleEnergy reports when a boundary window completes (once per segment).
struct SegmentEnergy {
  std::int64_t t_ns = 0;        ///< time of the tooth that completed the boundary window (ns)
  int boundary = 0;             ///< firing position whose segment STARTS at this boundary (0 = cylinder 1)
  int ended_position = 0;       ///< firing position whose segment just ENDED (boundary − 1, wrapped)
  double ke_j = 0.0;            ///< window-mean ½Jθ̇² at this boundary (J)
  double speed_rad_s = 0.0;     ///< window-mean θ̇ (rad/s)
  bool segment_valid = false;   ///< the previous boundary was measured with no tooth missing in between
  double d_ke_segment_j = 0.0;  ///< KE(this) − KE(previous boundary) (J)
  double segment_rad = 0.0;     ///< angle between the two boundaries (rad)
  double segment_dt_s = 0.0;    ///< time between the two window completions (s)
  double load_mean_nm = 0.0;    ///< angle-mean of the load torque given to update() over the segment (N m)
  bool load_valid = false;      ///< every tooth of the segment had a valid load
  bool cycle_valid = false;     ///< the last n_cyl segments are all valid (rolling 720° balance available)
  double d_ke_cycle_j = 0.0;    ///< KE(this) − KE(same boundary one cycle earlier) (J)
  double cycle_dt_s = 0.0;      ///< duration of that 720° (s)
  double cycle_load_mean_nm = 0.0;  ///< angle-mean load over that 720° (N m)
  bool cycle_load_valid = false;
};

class CycleEnergy {
 public:
  /// KE windows of params.energy_window_deg centred on each boundary (±w/2).
  CycleEnergy(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params);
  /// KE windows of `window_deg` ending `window_end_deg` after each boundary: [end − window, end) (the
  /// per-cylinder segment work's wider window, AnglePipeline). Windows of neighbouring boundaries must not
  /// overlap: window_deg < 720°/cylinders (checked by the config loader).
  /// `taper` in [0, 1] weights each tooth period by 1 − taper·(2x − 1)², x its centre's position in the
  /// window (0 = rectangle; 1 = parabola: the edge jitter enters through every edge with a small weight
  /// instead of through the two outer edges with weight 1/n, see EnergiesParams::cylinder_window_taper).
  CycleEnergy(const EngineGeometry& engine, const WheelGeometry& wheel, const EnergiesParams& params,
              double window_deg, double window_end_deg, double taper = 0.0);

  void reset() noexcept;
  /// Real-time safe. `load_nm` is the load torque at this tooth (dyno / e-machine), `load_valid` whether
  /// known. Returns true when a boundary window completed on this tooth; then segment() holds the new record.
  bool update(const ToothSample& s, double load_nm, bool load_valid) noexcept;
  /// update() for a sample already checked as update() does (synced, finite positive dt and width, tooth in
  /// [0, samples())): AnglePipeline::on_tooth checks once per tooth. Real-time safe.
  bool update_checked(const ToothSample& s, double load_nm, bool load_valid) noexcept;
  [[nodiscard]] const SegmentEnergy& segment() const noexcept { return seg_; }

  [[nodiscard]] int samples() const noexcept { return samples_; }
  [[nodiscard]] int cylinders() const noexcept { return ncyl_; }
  /// Nominal centre angle of the period ending at tooth k, relative to cylinder 1's firing TDC, in [0, 4π).
  [[nodiscard]] double center_rad(int k) const noexcept { return center_[static_cast<std::size_t>(k)]; }
  /// Nominal width of the period ending at tooth k (rad).
  [[nodiscard]] double nominal_width_rad(int k) const noexcept { return width_[static_cast<std::size_t>(k)]; }
  /// J at that centre (kg m²).
  [[nodiscard]] double inertia_center(int k) const noexcept { return j_center_[static_cast<std::size_t>(k)]; }
  /// Angle of boundary b relative to cylinder 1's firing TDC (rad).
  [[nodiscard]] double boundary_rad(int b) const noexcept { return boundary_[static_cast<std::size_t>(b)]; }
  /// Number of tooth-sequence breaks (missing / out-of-order teeth) seen (each invalidates the open windows).
  [[nodiscard]] std::uint64_t breaks() const noexcept { return breaks_; }
  /// Teeth whose load had to be extrapolated because the delay line was full (τ longer than its capacity).
  [[nodiscard]] std::uint64_t latency_overflows() const noexcept { return overflows_; }

 private:
  void invalidate() noexcept;
  void track_load(const ToothSample& s, bool first_after_break, double load_nm, bool load_valid) noexcept;
  void finish_window(const ToothSample& s, int b) noexcept;
  int samples_ = 0, ncyl_ = 0;
  std::vector<double> center_, width_, j_center_;
  std::vector<double> kern_w_;     ///< KE window weight of tooth k: its width × the window taper (rad)
  std::vector<int> window_of_;     ///< boundary whose KE window holds tooth k, −1 if none
  std::vector<int> window_first_;  ///< 1 if tooth k opens its window
  std::vector<int> window_last_;   ///< 1 if tooth k closes its window
  std::vector<int> segment_of_;    ///< firing position whose segment holds tooth k's centre
  std::array<double, kMaxCylinders> boundary_{};

  /// A tooth period waiting for the load of its time (t + τ) to arrive.
  struct PendingTooth {
    std::int64_t t_ns = 0;
    int segment = 0;
    double width_rad = 0.0;
  };
  void add_load(int segment, double width_rad, double load_nm, bool load_valid) noexcept;
  void flush_pending(double load_nm, bool load_valid) noexcept;

  std::int64_t latency_ns_ = 0;
  std::vector<PendingTooth> pending_;  ///< ring buffer, sized at construction
  std::size_t pend_head_ = 0, pend_count_ = 0;
  /// i + 1 modulo the ring size, for i < size (a `%` by the run-time size was a 64-bit division per tooth).
  [[nodiscard]] std::size_t ring_next(std::size_t i) const noexcept {
    return i + 1 == pending_.size() ? 0 : i + 1;
  }
  std::uint64_t overflows_ = 0;

  // Running state.
  int expected_tooth_ = -1;
  double win_ke_w_ = 0.0, win_w_ = 0.0, win_speed_w_ = 0.0;
  bool win_open_ = false;
  std::array<double, kMaxCylinders> seg_load_w_{};  ///< Σ load·w per firing segment being accumulated
  std::array<double, kMaxCylinders> seg_w_{};
  std::array<bool, kMaxCylinders> seg_load_ok_{};
  std::array<double, kMaxCylinders> ke_{};       ///< last KE per boundary
  std::array<std::int64_t, kMaxCylinders> t_{};  ///< completion time per boundary
  std::array<bool, kMaxCylinders> ke_valid_{};
  std::array<bool, kMaxCylinders> seg_ok_{};  ///< last segment ending at boundary b was valid
  std::array<double, kMaxCylinders> seg_load_mean_{};
  std::array<bool, kMaxCylinders> seg_load_mean_ok_{};
  std::array<double, kMaxCylinders> seg_angle_{};
  int last_boundary_ = -1;
  std::uint64_t breaks_ = 0;
  SegmentEnergy seg_;
};

}  // namespace torqued
