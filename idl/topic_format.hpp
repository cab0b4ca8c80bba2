#pragma once
// Text forms of torque samples: CSV (first column t_ns = source_t_ns, then every field by name; arrays expand
// to name_1..name_8), JSON lines, and a short human line. Used by the daemon's recorder and torque-echo, so
// both write the same columns. Not real-time code (appends to a std::string); locale-free numbers: the same
// sample always gives the same bytes. CSV: integers exact, doubles rounded to the column's resolution
// (csv_number.hpp: 6 decimals, 9 for *_rad, 3 for *_rad_s2; shortest round-trip when smaller than 4
// significant digits at that resolution); JSON: shortest round-trip (std::to_chars).
#include <string>
#include <string_view>

#include "topics.hpp"

namespace torqued::dds {

/// The fields every topic carries after its key (sequence number, the three time stamps, the
/// validity bits), in declaration order.
template <class S, class F>
constexpr void visit_stamps(const S& s, F&& f) {
  f("seq", s.seq);
  f("source_t_ns", s.source_t_ns);
  f("ingest_t_ns", s.ingest_t_ns);
  f("publish_t_ns", s.publish_t_ns);
  f("validity", s.validity);
}

/// Calls f(name, value) for each field in declaration order (arrays: f(name, array, count)). constexpr: the
/// CSV row plan (decimals per column) is computed at compile time.
template <class F>
constexpr void visit_fields(const torque_EngineTorque& s, F&& f) {
  f("engine_id", s.engine_id);
  visit_stamps(s, f);
  f("kind", s.kind);
  f("cylinder", s.cylinder);
  f("cycle", s.cycle);
  f("window_start_t_ns", s.window_start_t_ns);
  f("speed_rad_s", s.speed_rad_s);
  f("brake_nm", s.brake_nm);
  f("indicated_nm", s.indicated_nm);
  f("friction_nm", s.friction_nm);
  f("load_nm", s.load_nm);
  f("fused_nm", s.fused_nm);
  f("quality", s.quality);
  f("fused_source", s.fused_source);
  f("input_age_ns", s.input_age_ns);
}
template <class F>
constexpr void visit_fields(const torque_EstimatorTorque& s, F&& f) {
  f("engine_id", s.engine_id);
  f("method", s.method);
  visit_stamps(s, f);
  f("value_nm", s.value_nm);
  f("uncertainty", s.uncertainty);
  f("health", s.health);
}
template <class F>
constexpr void visit_fields(const torque_CylinderTorque& s, F&& f) {
  f("engine_id", s.engine_id);
  visit_stamps(s, f);
  f("cycle", s.cycle);
  f("cylinders", s.cylinders);
  f("indicated_nm", s.indicated_nm, 8);
  f("imbalance_pct", s.imbalance_pct, 8);
  f("imbalance_filtered_pct", s.imbalance_filtered_pct, 8);
  f("imbalance_sd_pct", s.imbalance_sd_pct);
  f("misfire_mask", s.misfire_mask);
  f("health", s.health);
}
template <class F>
constexpr void visit_fields(const torque_CrankState& s, F&& f) {
  f("engine_id", s.engine_id);
  visit_stamps(s, f);
  f("tooth", s.tooth);
  f("sync", s.sync);
  f("phase_known", s.phase_known);
  f("angle_rad", s.angle_rad);
  f("speed_rad_s", s.speed_rad_s);
  f("accel_rad_s2", s.accel_rad_s2);
  f("events", s.events);
}
template <class F>
constexpr void visit_fields(const torque_DaemonStatus& s, F&& f) {
  f("engine_id", s.engine_id);
  visit_stamps(s, f);
  f("health", s.health);
  f("flags", s.flags);
  f("uptime_ns", s.uptime_ns);
  f("edges", s.edges);
  f("teeth", s.teeth);
  f("can_frames", s.can_frames);
  f("cycles", s.cycles);
  f("sync_losses", s.sync_losses);
  f("ring_drops_edge", s.ring_drops_edge);
  f("ring_drops_can", s.ring_drops_can);
  f("ring_drops_out", s.ring_drops_out);
  f("source_drops", s.source_drops);
  f("overruns", s.overruns);
  f("latency_p50_ns", s.latency_p50_ns);
  f("latency_p99_ns", s.latency_p99_ns);
  f("latency_max_ns", s.latency_max_ns);
  f("sensor_timeouts", s.sensor_timeouts);
  f("publisher_polls", s.publisher_polls);
  f("publisher_poll_misses", s.publisher_poll_misses);
  f("rejected_edges", s.rejected_edges);
  f("cam_phase_errors", s.cam_phase_errors);
  f("fuel_references", s.fuel_references);
  f("fuel_cells", s.fuel_cells);
  f("burn_phase_state", s.burn_phase_state);
  f("burn_phase_offset_deg", s.burn_phase_offset_deg);
}

/// CSV header line (with '\n') of a topic: "t_ns,engine_id,seq,...".
template <class T>
std::string csv_header();
/// Appends one CSV row (with '\n'); t_ns = source_t_ns first.
template <class T>
void append_csv_row(std::string& out, const T& s);
/// Upper bound of the length of one CSV row of T (with '\n'): the room write_csv_row needs.
template <class T>
std::size_t csv_row_max_chars() noexcept;
/// Writes one CSV row (with '\n') at p, which has room for csv_row_max_chars<T>() chars; returns the end.
/// Same bytes as append_csv_row (the recorder's path: no std::string in between).
template <class T>
char* write_csv_row(char* p, const T& s) noexcept;
/// Appends one JSON object line (with '\n') {"topic":"EngineTorque","engine_id":1,...}.
template <class T>
void append_json(std::string& out, const T& s);
/// Appends a compact human-readable line (with '\n') for the terminal table of torque-echo.
template <class T>
void append_table_row(std::string& out, const T& s);
/// Header line of the table for topic T.
template <class T>
std::string table_header();

}  // namespace torqued::dds
