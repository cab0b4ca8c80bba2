#pragma once
// torque-dash's live view of the torque topics: per engine_id, bounded rings of what the web page plots, and
// the JSON messages that carry them to the page (a full snapshot for a new page, deltas after that).
// Not real-time code (a subscriber process of its own); bounded memory: every ring has a fixed capacity and
// the oldest entries are overwritten.
//
// In-cycle indicated torque: EstimatorTorque of the registry's in-cycle methods (idl/methods.hpp `in_cycle`:
// Kalman, Fourier) carry the time of the tooth edge they refer to but no angle; CrankState (every
// dds.crank_state_decimation-th tooth) carries (time, angle within 720°). A sample's angle is interpolated
// between the two CrankState anchors around its time; samples wait (bounded) until the later anchor has
// arrived. A new cycle starts when the angle wraps.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "methods.hpp"
#include "physical_range.hpp"
#include "topics.hpp"

namespace torqued::dash {

/// Fixed-capacity ring; `total()` counts every push (the delta cursor of a page).
template <class T>
class Ring {
 public:
  explicit Ring(std::size_t capacity = 1) : buf_(capacity) {}
  void push(const T& v) {
    buf_[static_cast<std::size_t>(total_ % buf_.size())] = v;
    ++total_;
  }
  [[nodiscard]] std::uint64_t total() const noexcept { return total_; }
  [[nodiscard]] std::size_t size() const noexcept {
    return static_cast<std::size_t>(std::min<std::uint64_t>(total_, buf_.size()));
  }
  /// Entry number i (0 = first ever pushed); valid for total()-size() <= i < total().
  [[nodiscard]] const T& at(std::uint64_t i) const { return buf_[static_cast<std::size_t>(i % buf_.size())]; }
  [[nodiscard]] std::uint64_t first() const noexcept { return total_ - size(); }

 private:
  std::vector<T> buf_;
  std::uint64_t total_ = 0;
};

struct TorquePoint {  ///< one EngineTorque sample (segment or cycle)
  double t_s = 0, rpm = 0, brake = 0, indicated = 0, fused = 0;
  std::uint32_t cycle = 0, validity = 0;
  std::uint8_t kind = 0, cylinder = 0, quality = 0;
};
struct InCyclePoint {  ///< one sample of an in-cycle method placed on the crank angle
  double t_s = 0, angle_deg = 0, value = 0;
  std::uint64_t cycle = 0;  ///< dashboard cycle counter (angle wraps)
  std::uint8_t method = 0, health = 0;
};
struct Anchor {
  std::int64_t t_ns = 0;
  double angle_rad = 0;
};

struct Limits {
  std::size_t torque_points =
      4096;  ///< EngineTorque ring per engine (≈16 s of segments+cycles at 6000 rpm, 4 cyl)
  std::size_t incycle_points =
      2048;                    ///< in-cycle ring per engine (≈ 25 cycles of 2 methods at every 2nd tooth)
  std::size_t pending = 8192;  ///< in-cycle samples waiting for their CrankState anchor (≈1 s at 6000 rpm)
  std::size_t anchors = 1024;  ///< CrankState anchors kept for interpolation (≈1.7 s at 6000 rpm)
  std::size_t engines = 16;    ///< engine ids shown (more are counted and ignored)
};

struct EngineView {
  explicit EngineView(const Limits& l)
      : torque(l.torque_points), incycle(l.incycle_points), anchors(l.anchors) {}
  Ring<TorquePoint> torque;
  Ring<InCyclePoint> incycle;
  Ring<Anchor> anchors;
  std::vector<torque_EstimatorTorque> pending;  ///< sorted by arrival; bounded by Limits::pending
  bool have_cylinder = false, have_status = false, have_crank = false;
  torque_CylinderTorque cylinder{};
  torque_DaemonStatus status{};
  torque_CrankState crank{};
  std::uint64_t cylinder_version = 0, status_version = 0, crank_version = 0;
  std::array<std::uint64_t, 8> misfires{};  ///< misfired cycles per cylinder since the dashboard started
  std::array<double, 8> last_misfire_t_s{-1, -1, -1, -1, -1, -1, -1, -1};  ///< edge clock of the latest (s)
  std::uint64_t incycle_cycle = 0;
  double last_angle_deg = -1;
  std::uint64_t unplaced = 0;      ///< in-cycle samples dropped: no anchor around their time, or pending full
  std::uint64_t out_of_range = 0;  ///< samples outside the engine's physical range (not plotted, counted)
};

/// Cursor of one page into the model: what it has already been sent.
struct Cursor {
  struct PerEngine {
    std::uint64_t torque = 0, incycle = 0, cylinder = 0, status = 0, crank = 0;
  };
  std::map<std::uint16_t, PerEngine> engines;
  bool snapshot_sent = false;
};

/// Engine geometry for the TDC marks (from the daemon's configuration, optional).
struct Geometry {
  int cylinders = 0;                  ///< 0 = unknown (no TDC marks)
  std::array<int, 8> firing_order{};  ///< 1-based cylinder numbers
  double tdc_offset_deg = 0;          ///< crank angle of cylinder 1 firing TDC after tooth 0
  dds::TorqueRange range{};  ///< physical torque range (physical_range.hpp): samples outside are not plotted
};

class Model {
 public:
  explicit Model(Limits l = {}, Geometry g = {}) : limits_(l), geometry_(g) {}
  void add(const torque_EngineTorque& s);
  void add(const torque_EstimatorTorque& s);
  void add(const torque_CylinderTorque& s);
  void add(const torque_CrankState& s);
  void add(const torque_DaemonStatus& s);
  /// Drops an engine id (it went silent): its slot is free for another; cursors must forget it too.
  void forget(std::uint16_t engine_id) { engines_.erase(engine_id); }

  /// JSON message with everything after `c` (and advances it); "" when there is nothing new. A fresh cursor
  /// gets the whole rings plus the page's static data (geometry, the method registry: methods_json()) as
  /// {"type":"snapshot",...}.
  [[nodiscard]] std::string delta(Cursor& c) const;
  [[nodiscard]] const std::map<std::uint16_t, EngineView>& engines() const noexcept { return engines_; }
  [[nodiscard]] std::uint64_t ignored_engines() const noexcept { return ignored_; }

 private:
  EngineView* view(std::uint16_t engine_id);
  void place_pending(EngineView& v);
  [[nodiscard]] bool place(EngineView& v, const torque_EstimatorTorque& s);
  void append_engine(std::string& out, std::uint16_t id, const EngineView& v, Cursor::PerEngine& c) const;
  Limits limits_;
  Geometry geometry_;
  std::map<std::uint16_t, EngineView> engines_;
  std::uint64_t ignored_ = 0;
};

/// The method registry (idl/methods.hpp) as a JSON array of {id, name, label, domain, in_cycle}: the page's
/// method labels and which methods it draws on the crank angle (snapshot "methods", GET /api/methods).
std::string methods_json();
/// DaemonStatus flags as words ("DROPS", "NO_SYNC", ...), and the health word.
std::vector<std::string> status_flag_words(std::uint32_t flags);
const char* daemon_health_word(std::uint8_t health);

}  // namespace torqued::dash
