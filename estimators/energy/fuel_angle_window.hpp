#pragma once
// The fuel and MAP behind the work of one 720° energy-balance window (fuel model). A cylinder's
// fuel (and its trapped charge, ≈ MAP) is decided at its intake event, ≈ `intake_btdc_deg` before its firing
// TDC (IVC 40-60° after BDC, Heywood 1988 §6.3), and its work lands around `work_centroid_atdc_deg` after
// that TDC. The window [θ_end − 4π, θ_end] therefore holds, per cylinder, the work of the one combustion
// event whose centroid lies in it: the fuel model is evaluated on the CAN values seen at those intake events,
// not on the instantaneous CAN value (which leads the work by up to a cycle in a transient). Each intake
// event also records the fuel cut-off flag: a window straddling a cut-off entry or exit is split into its
// firing events (fuel model) and its cut-off events (no combustion: motored torque). The ECU's fuel mass
// reports the latest injection: at a cut-off exit an intake event can see the flag cleared while the fuel
// still reads 0; its fuel is then the next positive report (pending until it arrives). Per tooth: one
// comparison per cylinder. Real-time safe: fixed arrays, no allocation, no exceptions.
#include <array>
#include <cstdint>

#include "engine_geometry.hpp"

namespace torqued {

/// CAN values seen at one intake event.
struct FuelIntakeInput {
  double fuel_kg = 0.0;   ///< fuel per injection per cylinder (kg)
  double map_pa = 0.0;    ///< manifold pressure (Pa)
  bool fuel_cut = false;  ///< fuel cut-off flag set
  bool valid = false;     ///< CAN fresh, fuel mass and MAP known
};

/// What the window ending at a boundary holds.
struct FuelWindow {
  int fired = 0;              ///< combustion events in the window
  int cut = 0;                ///< events in fuel cut-off (no combustion)
  double fuel_kg = 0.0;       ///< mean fuel per injection of the fired events (kg)
  double map_fired_pa = 0.0;  ///< mean MAP at the fired events' intake (Pa)
  double map_cut_pa = 0.0;    ///< mean MAP at the cut-off events' intake (Pa)
  double fuel_min_kg = 0.0;   ///< smallest / largest fuel of the fired events (kg): transient spread
  double fuel_max_kg = 0.0;
  double map_min_pa = 0.0;  ///< smallest / largest MAP of all events (Pa)
  double map_max_pa = 0.0;
  bool valid = false;  ///< every cylinder has a valid event with its centroid in the window
};

class FuelAngleWindow {
 public:
  /// `tdc_rad[m]`: firing TDC of firing position m relative to cylinder 1's (rad, [0, 4π)).
  FuelAngleWindow(int cylinders, const std::array<double, kMaxCylinders>& tdc_rad, double intake_btdc_deg,
                  double work_centroid_atdc_deg, double report_window_s) noexcept;
  void reset() noexcept;
  /// A synced tooth at `rel_rad` (edge angle relative to cylinder 1's firing TDC, [0, 4π)) with the CAN
  /// values now. Records an intake event for every cylinder whose intake angle was passed since the previous
  /// tooth.
  void on_tooth(std::int64_t t_ns, double rel_rad, const FuelIntakeInput& in) noexcept;
  /// The sequence broke (no sync, missing teeth): events are forgotten.
  void break_sequence() noexcept { reset(); }
  /// The window ending at the last passage of `end_rel_rad` (relative to cylinder 1's TDC).
  [[nodiscard]] FuelWindow window(double end_rel_rad) const noexcept;

 private:
  struct Event {
    double centroid_rad = 0.0;  ///< unwrapped angle of this event's work centroid (rad)
    FuelIntakeInput in{};
    bool set = false;
    bool fuel_pending = false;  ///< firing, but the ECU had not reported this injection yet (fuel read 0)
  };
  static void revise(Event& e, const FuelIntakeInput& in) noexcept;
  static constexpr int kDepth = 2;  ///< events kept per cylinder: intake→centroid < 720° by the schema bounds
  int n_;
  std::array<double, kMaxCylinders> intake_rel_{};             ///< intake angle per position (rad, [0, 4π))
  double lead_rad_;                                            ///< intake → work centroid (rad)
  std::array<std::array<Event, kDepth>, kMaxCylinders> ev_{};  ///< newest first
  double unwrapped_ = 0.0;                                     ///< angle since reset (rad)
  double last_fuel_kg_ = 0.0;  ///< newest positive fuel report (kg): fills pending events
  int open_ = -1;              ///< position of the newest event: revised by reports until the next intake
  std::int64_t open_until_ns_ = 0;  ///< ... or until this time (ns)
  double open_until_rad_ = 0.0;  ///< ... or half a firing interval after its intake (unwrapped, rad): a later
                                 ///< report may already be the next cylinder's decision
  std::int64_t report_window_ns_;
  double prev_rel_ = 0.0;
  bool have_prev_ = false;
  bool any_pending_ =
      false;  ///< some event may be fuel_pending (none when false): skips the fill pass per tooth
};

}  // namespace torqued
