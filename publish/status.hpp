#pragma once
// Daemon statistics gathered into one DaemonStatus sample. Filled by the supervisor (paced/live) or the
// fast replay loop from the stages' counters, the rings' drop counters and the sources' stats.
#include <cstdint>

#include "sample.hpp"

namespace torqued {

struct RuntimeCounters {
  std::uint64_t edges = 0, teeth = 0, can_frames = 0, cycles = 0, sync_losses = 0;
  std::uint64_t ring_drops_edge = 0, ring_drops_can = 0, ring_drops_out = 0, source_drops = 0, overruns = 0;
  std::int64_t latency_p50_ns = 0, latency_p99_ns = 0, latency_max_ns = 0;  ///< last status period
  std::int64_t run_latency_p50_ns = 0, run_latency_p99_ns = 0, run_latency_max_ns = 0;  ///< whole run
  /// Publisher pre-wakes (paced replay) and those whose poll ended without a sample.
  std::uint64_t publisher_polls = 0, publisher_poll_misses = 0;
  std::uint64_t rejected_edges = 0, cam_phase_errors = 0;  ///< decoder: glitches rejected, cam disagreements
  std::uint32_t fuel_references = 0;  ///< references the fuel model rests on (0: prior only)
  std::uint16_t fuel_cells = 0;
  std::uint8_t burn_phase_state = 0;   ///< BurnPhaseState of the burn-phasing learner (0 also: off)
  double burn_phase_offset_deg = 0.0;  ///< its learned offset (deg)
  /// Imported tooth tables the running engine contradicted (discarded, relearned); not in DaemonStatus.
  std::uint64_t tooth_tables_distrusted =
      0;  ///< learned speed × MAP cells of the fuel model (FuelTorque::learned_cells)
  /// Paced replay / live: times the angle thread slept (one wake-up each); not in DaemonStatus (no field).
  std::uint64_t angle_wakeups = 0;
  std::uint32_t flags = 0;            ///< torque_STATUS_*
  std::uint32_t sensor_timeouts = 0;  ///< bit per EngineSignals quantity
  bool synced = false;
};

/// Builds the status sample from the counters (monotonic, whole run) and what changed since `prev` (the
/// previous status): DROPS and OVERRUNS say "since the previous status" and clear when the condition has
/// gone; the counters keep the history. Health: DEGRADED while any condition flag is set, FAILED when not
/// synced and no edges come; once REPLAY_DONE, the ended input's flags (no sync, edge/CAN timeout) do not
/// count.
inline dds::AnySample make_status(const RuntimeCounters& c, const RuntimeCounters& prev, std::uint64_t seq,
                                  std::int64_t source_t_ns, std::int64_t uptime_ns) noexcept {
  dds::AnySample a;
  a.topic = dds::Topic::kDaemonStatus;
  auto& s = a.u.status;
  s.seq = seq;
  s.source_t_ns = source_t_ns;
  s.uptime_ns = uptime_ns;
  s.edges = c.edges;
  s.teeth = c.teeth;
  s.can_frames = c.can_frames;
  s.cycles = c.cycles;
  s.sync_losses = c.sync_losses;
  s.ring_drops_edge = c.ring_drops_edge;
  s.ring_drops_can = c.ring_drops_can;
  s.ring_drops_out = c.ring_drops_out;
  s.source_drops = c.source_drops;
  s.overruns = c.overruns;
  s.latency_p50_ns = c.latency_p50_ns;
  s.latency_p99_ns = c.latency_p99_ns;
  s.latency_max_ns = c.latency_max_ns;
  s.sensor_timeouts = c.sensor_timeouts;
  s.publisher_polls = c.publisher_polls;
  s.publisher_poll_misses = c.publisher_poll_misses;
  s.rejected_edges = c.rejected_edges;
  s.cam_phase_errors = c.cam_phase_errors;
  s.fuel_references = c.fuel_references;
  s.fuel_cells = c.fuel_cells;
  s.burn_phase_state = c.burn_phase_state;
  s.burn_phase_offset_deg = c.burn_phase_offset_deg;
  s.flags = c.flags;
  const auto dropped = [](const RuntimeCounters& x) {
    return x.ring_drops_edge + x.ring_drops_can + x.ring_drops_out + x.source_drops;
  };
  if (!c.synced) s.flags |= torque_STATUS_NO_SYNC;
  if (c.sensor_timeouts) s.flags |= torque_STATUS_CAN_TIMEOUT;
  if (dropped(c) > dropped(prev)) s.flags |= torque_STATUS_DROPS;
  if (c.overruns > prev.overruns) s.flags |= torque_STATUS_OVERRUNS;
  s.health = torque_DAEMON_OK;
  // A replay that has consumed its recording is done, not faulty: no sync, no edges and stale CAN are what
  // its end looks like, and do not degrade health (the flags still say so).
  const bool done = (s.flags & torque_STATUS_REPLAY_DONE) != 0;
  const std::uint32_t input_ended =
      done ? (torque_STATUS_NO_SYNC | torque_STATUS_CAN_TIMEOUT | torque_STATUS_EDGE_TIMEOUT) : 0u;
  if (s.flags & ~input_ended &
      (torque_STATUS_NO_SYNC | torque_STATUS_CAN_TIMEOUT | torque_STATUS_DROPS | torque_STATUS_OVERRUNS |
       torque_STATUS_EDGE_TIMEOUT | torque_STATUS_RT_NOT_PERMITTED | torque_STATUS_MLOCK_FAILED |
       torque_STATUS_RECORD_ERROR))
    s.health = torque_DAEMON_DEGRADED;
  if (!done && !c.synced && (s.flags & torque_STATUS_EDGE_TIMEOUT)) s.health = torque_DAEMON_FAILED;
  if (!c.synced) s.validity |= torque_VALIDITY_NO_SYNC;
  return a;
}

/// The status samples of one run: keeps the previous counters so each sample's condition flags cover the time
/// since the previous one.
class StatusTracker {
 public:
  dds::AnySample next(const RuntimeCounters& c, std::int64_t source_t_ns, std::int64_t uptime_ns) noexcept {
    dds::AnySample a = make_status(c, prev_, ++seq_, source_t_ns, uptime_ns);
    prev_ = c;
    return a;
  }

 private:
  RuntimeCounters prev_{};
  std::uint64_t seq_ = 0;
};

}  // namespace torqued
