#pragma once
// Fixed-size records that io/ sources hand over lock-free rings to the pipelines. Trivially copyable.
#include <array>
#include <cstdint>

namespace torqued {

/// One logic-level transition on a capture channel (crank, cam, ...).
struct EdgeEvent {
  std::int64_t t_ns = 0;     ///< source timestamp (ns); capture time base or CLOCK_REALTIME/kernel time
  std::uint8_t channel = 0;  ///< 0 = crank, 1 = cam (as mapped by the source)
  std::uint8_t level = 0;    ///< level after the transition (1 = rising edge)
};

/// One CAN or CAN FD frame.
struct CanFrame {
  std::int64_t t_ns = 0;  ///< receive timestamp (ns)
  std::uint32_t id = 0;   ///< identifier without flag bits
  bool extended = false;  ///< 29-bit identifier
  bool fd = false;        ///< CAN FD frame
  std::uint8_t len = 0;   ///< payload length in bytes (0..64)
  std::uint8_t bus = 0;   ///< interface index as configured
  std::array<std::uint8_t, 64> data{};
};

enum class SyncState : std::uint8_t { kNoSignal = 0, kSyncing = 1, kSynced = 2, kLostSync = 3, kStalled = 4 };

/// One decoded tooth from the crank decoder.
struct ToothEvent {
  std::int64_t t_ns = 0;         ///< edge timestamp (ns)
  std::int64_t source_t_ns = 0;  ///< the edge's source time (same clock as the capture)
  std::int32_t tooth = 0;        ///< tooth index within 720° (0 .. 2*teeth-1), valid when synced
  double angle_rad = 0.0;    ///< angle within 720° of this edge, corrected by the tooth table when learned
  double width_rad = 0.0;    ///< true angular width of the tooth period ending at this edge (rad)
  double speed_rad_s = 0.0;  ///< width_rad / period
  SyncState sync = SyncState::kNoSignal;
  bool phase_known = false;  ///< 720° phase established from the cam edge
  std::uint32_t events = 0;  ///< bit flags: see ToothFlags
};

enum ToothFlags : std::uint32_t {
  kToothNoiseRejected = 1u << 0,  ///< a runt edge before this tooth was rejected
  kToothLostRecovered = 1u << 1,  ///< a lost tooth was interpolated
  kToothResynced = 1u << 2,
  kToothGap = 1u << 3,  ///< this edge closes the missing-tooth gap
};

}  // namespace torqued
