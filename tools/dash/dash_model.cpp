#include "dash_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace torqued::dash {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kRadSToRpm = 60.0 / (2.0 * std::numbers::pi);

double seconds(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

/// Appends a number; non-finite values become null (JSON has no NaN).
void num(std::string& out, double v, const char* fmt = "%.3f") {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[48];
  const int n = std::snprintf(buf, sizeof buf, fmt, v);
  out.append(buf, static_cast<std::size_t>(std::clamp(n, 0, static_cast<int>(sizeof buf) - 1)));
}
void num(std::string& out, std::uint64_t v) { out += std::to_string(v); }

void append_status(std::string& out, const torque_DaemonStatus& s) {
  out += "{\"t_s\":";
  num(out, seconds(s.source_t_ns), "%.3f");
  out += ",\"health\":\"";
  out += daemon_health_word(s.health);
  out += "\",\"flags\":[";
  bool first = true;
  for (const auto& w : status_flag_words(s.flags)) {
    out += first ? "\"" : ",\"";
    out += w;
    out += '"';
    first = false;
  }
  out += "],\"uptime_s\":";
  num(out, seconds(s.uptime_ns), "%.1f");
  const std::pair<const char*, std::uint64_t> counters[] = {{"edges", s.edges},
                                                            {"teeth", s.teeth},
                                                            {"can_frames", s.can_frames},
                                                            {"cycles", s.cycles},
                                                            {"sync_losses", s.sync_losses},
                                                            {"ring_drops_edge", s.ring_drops_edge},
                                                            {"ring_drops_can", s.ring_drops_can},
                                                            {"ring_drops_out", s.ring_drops_out},
                                                            {"source_drops", s.source_drops},
                                                            {"overruns", s.overruns},
                                                            {"sensor_timeouts", s.sensor_timeouts},
                                                            {"fuel_references", s.fuel_references},
                                                            {"fuel_cells", s.fuel_cells},
                                                            {"seq", s.seq}};
  for (const auto& [name, v] : counters) {
    out += ",\"";
    out += name;
    out += "\":";
    num(out, v);
  }
  out += ",\"burn_phase_state\":";
  num(out, static_cast<std::uint64_t>(s.burn_phase_state));
  out += ",\"burn_phase_offset_deg\":";
  num(out, s.burn_phase_offset_deg, "%.2f");
  out += ",\"latency_us\":[";
  num(out, static_cast<double>(s.latency_p50_ns) * 1e-3, "%.1f");
  out += ',';
  num(out, static_cast<double>(s.latency_p99_ns) * 1e-3, "%.1f");
  out += ',';
  num(out, static_cast<double>(s.latency_max_ns) * 1e-3, "%.1f");
  out += "]}";
}

void append_cylinder(std::string& out, const torque_CylinderTorque& s, const EngineView& v) {
  out += "{\"t_s\":";
  num(out, seconds(s.source_t_ns), "%.3f");
  out += ",\"cycle\":" + std::to_string(s.cycle) + ",\"misfire_mask\":" + std::to_string(s.misfire_mask) +
         ",\"health\":" + std::to_string(s.health) + ",\"indicated\":[";
  const int n = std::min<int>(s.cylinders, 8);
  for (int i = 0; i < n; ++i) {
    if (i) out += ',';
    num(out, s.indicated_nm[i], "%.2f");
  }
  out += "],\"imbalance_pct\":[";
  for (int i = 0; i < n; ++i) {
    if (i) out += ',';
    num(out, s.imbalance_pct[i], "%.2f");
  }
  out +=
      "],\"misfires\":[";  // counts since the dashboard started, and when the latest was (misfires flash by)
  for (int i = 0; i < n; ++i) out += (i ? "," : "") + std::to_string(v.misfires[static_cast<std::size_t>(i)]);
  out += "],\"last_misfire_t_s\":[";
  for (int i = 0; i < n; ++i) {
    if (i) out += ',';
    num(out, v.last_misfire_t_s[static_cast<std::size_t>(i)], "%.3f");
  }
  out += "]}";
}

void append_crank(std::string& out, const torque_CrankState& s) {
  out += "{\"t_s\":";
  num(out, seconds(s.source_t_ns), "%.3f");
  out += ",\"rpm\":";
  num(out, s.speed_rad_s * kRadSToRpm, "%.1f");
  out += ",\"angle_deg\":";
  num(out, s.angle_rad * kRadToDeg, "%.1f");
  out += ",\"tooth\":" + std::to_string(s.tooth) + ",\"sync\":" + std::to_string(s.sync) +
         ",\"phase_known\":" + (s.phase_known ? "true" : "false") + "}";
}

void append_geometry(std::string& out, const Geometry& g) {
  out += "\"geometry\":{\"cylinders\":" + std::to_string(g.cylinders) + ",\"tdc_deg\":[";
  // Firing position k (0-based) has its TDC at offset + k * 720 / n; the mark names the cylinder.
  for (int k = 0; k < g.cylinders && k < 8; ++k) {
    if (k) out += ',';
    out += "{\"cylinder\":" + std::to_string(g.firing_order[static_cast<std::size_t>(k)]) + ",\"deg\":";
    num(out, std::fmod(g.tdc_offset_deg + 720.0 * k / g.cylinders, 720.0), "%.2f");
    out += '}';
  }
  out += "]},";
}

}  // namespace

std::string methods_json() {
  std::string out = "[";
  for (const auto& m : dds::kMethods) {
    if (out.size() > 1) out += ',';
    out += "{\"id\":" + std::to_string(m.id) + ",\"name\":\"" + std::string(m.name) + "\",\"label\":\"" +
           std::string(m.label) + "\",\"domain\":\"" + std::string(dds::domain_name(m.domain)) +
           "\",\"in_cycle\":" + (m.in_cycle ? "true" : "false") + '}';
  }
  return out + ']';
}

const char* daemon_health_word(std::uint8_t health) {
  switch (health) {
    case torque_DAEMON_OK:
      return "OK";
    case torque_DAEMON_DEGRADED:
      return "DEGRADED";
    case torque_DAEMON_FAILED:
      return "FAILED";
    default:
      return "UNKNOWN";
  }
}

std::vector<std::string> status_flag_words(std::uint32_t flags) {
  static constexpr std::pair<std::uint32_t, const char*> kWords[] = {
      {torque_STATUS_RT_NOT_PERMITTED, "RT_NOT_PERMITTED"},
      {torque_STATUS_MLOCK_FAILED, "MLOCK_FAILED"},
      {torque_STATUS_EDGE_TIMEOUT, "EDGE_TIMEOUT"},
      {torque_STATUS_CAN_TIMEOUT, "CAN_TIMEOUT"},
      {torque_STATUS_NO_SYNC, "NO_SYNC"},
      {torque_STATUS_DROPS, "DROPS"},
      {torque_STATUS_REPLAY_DONE, "REPLAY_DONE"},
      {torque_STATUS_DRAINING, "DRAINING"},
      {torque_STATUS_OVERRUNS, "OVERRUNS"},
      {torque_STATUS_RECORD_ERROR, "RECORD_ERROR"}};
  std::vector<std::string> out;
  std::uint32_t known = 0;
  for (const auto& [bit, word] : kWords) {
    known |= bit;
    if (flags & bit) out.emplace_back(word);
  }
  if (flags & ~known) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "UNKNOWN_0x%x", flags & ~known);
    out.emplace_back(buf);
  }
  return out;
}

EngineView* Model::view(std::uint16_t engine_id) {
  auto it = engines_.find(engine_id);
  if (it != engines_.end()) return &it->second;
  if (engines_.size() >= limits_.engines) {
    ++ignored_;
    return nullptr;
  }
  return &engines_.emplace(engine_id, EngineView(limits_)).first->second;
}

void Model::add(const torque_EngineTorque& s) {
  EngineView* v = view(s.engine_id);
  if (!v) return;
  if (!dds::in_range(s, geometry_.range)) {  // a foreign or corrupt writer: flagged, not plotted
    ++v->out_of_range;
    return;
  }
  v->torque.push(TorquePoint{seconds(s.source_t_ns), s.speed_rad_s * kRadSToRpm, s.brake_nm, s.indicated_nm,
                             s.fused_nm, s.cycle, s.validity, s.kind, s.cylinder, s.quality});
}

void Model::add(const torque_EstimatorTorque& s) {
  if (!dds::is_in_cycle(s.method)) return;  // the registry's instantaneous methods only
  EngineView* v = view(s.engine_id);
  if (!v) return;
  if (!dds::in_range(s, geometry_.range)) {
    ++v->out_of_range;
    return;
  }
  if (v->pending.size() >= limits_.pending) {  // no anchors arrive (CrankState not published): oldest go
    v->pending.erase(v->pending.begin());
    ++v->unplaced;
  }
  v->pending.push_back(s);
  place_pending(*v);
}

void Model::add(const torque_CylinderTorque& s) {
  EngineView* v = view(s.engine_id);
  if (!v) return;
  v->cylinder = s;
  v->have_cylinder = true;
  for (int i = 0; i < 8 && i < s.cylinders; ++i)
    if (s.misfire_mask & (1u << i)) {
      ++v->misfires[static_cast<std::size_t>(i)];
      v->last_misfire_t_s[static_cast<std::size_t>(i)] = seconds(s.source_t_ns);
    }
  ++v->cylinder_version;
}

void Model::add(const torque_CrankState& s) {
  EngineView* v = view(s.engine_id);
  if (!v) return;
  v->crank = s;
  v->have_crank = true;
  ++v->crank_version;
  if (s.sync != 2 || !s.phase_known || s.tooth < 0) return;  // no angle within 720° yet
  if (v->anchors.total() > 0 && v->anchors.at(v->anchors.total() - 1).t_ns >= s.source_t_ns) return;
  v->anchors.push(Anchor{s.source_t_ns, s.angle_rad});
  place_pending(*v);
}

void Model::add(const torque_DaemonStatus& s) {
  EngineView* v = view(s.engine_id);
  if (!v) return;
  v->status = s;
  v->have_status = true;
  ++v->status_version;
}

void Model::place_pending(EngineView& v) {
  if (v.anchors.total() == 0) return;
  const std::int64_t newest = v.anchors.at(v.anchors.total() - 1).t_ns;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < v.pending.size(); ++i) {
    const auto& s = v.pending[i];
    if (s.source_t_ns > newest) {
      v.pending[kept++] = s;  // its later anchor has not arrived yet
    } else if (!place(v, s)) {
      ++v.unplaced;
    }
  }
  v.pending.resize(kept);
}

bool Model::place(EngineView& v, const torque_EstimatorTorque& s) {
  // The newest anchor pair [a, b] with a.t <= s.t <= b.t (anchors are in time order).
  for (std::uint64_t i = v.anchors.total() - 1; i > v.anchors.first(); --i) {
    const Anchor& b = v.anchors.at(i);
    const Anchor& a = v.anchors.at(i - 1);
    if (a.t_ns > s.source_t_ns) continue;
    if (b.t_ns < s.source_t_ns || b.t_ns <= a.t_ns) return false;
    double span = b.angle_rad - a.angle_rad;  // forward rotation, across the 720° wrap
    if (span < 0) span += 4.0 * std::numbers::pi;
    const double f = static_cast<double>(s.source_t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
    double deg = std::fmod((a.angle_rad + f * span) * kRadToDeg, 720.0);
    if (deg >= 719.995) deg = 0.0;  // printed with 2 decimals: 719.999 would read 720.00
    if (v.last_angle_deg >= 0 && deg + 360.0 < v.last_angle_deg) ++v.incycle_cycle;  // wrapped: next cycle
    v.last_angle_deg = deg;
    v.incycle.push(
        InCyclePoint{seconds(s.source_t_ns), deg, s.value_nm, v.incycle_cycle, s.method, s.health});
    return true;
  }
  return false;
}

void Model::append_engine(std::string& out, std::uint16_t id, const EngineView& v,
                          Cursor::PerEngine& c) const {
  out += '"' + std::to_string(id) + "\":{\"torque\":[";
  for (std::uint64_t i = std::max(c.torque, v.torque.first()); i < v.torque.total(); ++i) {
    const TorquePoint& p = v.torque.at(i);
    if (out.back() != '[') out += ',';
    out += '[';
    num(out, p.t_s, "%.6f");
    out +=
        ',' + std::to_string(p.kind) + ',' + std::to_string(p.cylinder) + ',' + std::to_string(p.cycle) + ',';
    num(out, p.rpm, "%.1f");
    for (double x : {p.brake, p.indicated, p.fused}) {
      out += ',';
      num(out, x, "%.2f");
    }
    out += ',' + std::to_string(p.quality) + ',' + std::to_string(p.validity) + ']';
  }
  out += "],\"incycle\":[";
  for (std::uint64_t i = std::max(c.incycle, v.incycle.first()); i < v.incycle.total(); ++i) {
    const InCyclePoint& p = v.incycle.at(i);
    if (out.back() != '[') out += ',';
    out += '[';
    num(out, p.t_s, "%.6f");
    out += ',' + std::to_string(p.cycle) + ',';
    num(out, p.angle_deg, "%.2f");
    out += ',' + std::to_string(p.method) + ',';
    num(out, p.value, "%.2f");
    out += ',' + std::to_string(p.health) + ']';
  }
  out += ']';
  if (v.have_cylinder && c.cylinder != v.cylinder_version)
    append_cylinder(out += ",\"cylinder\":", v.cylinder, v);
  if (v.have_status && c.status != v.status_version) append_status(out += ",\"status\":", v.status);
  if (v.have_crank && c.crank != v.crank_version) append_crank(out += ",\"crank\":", v.crank);
  out += ",\"unplaced\":" + std::to_string(v.unplaced) +
         ",\"out_of_range\":" + std::to_string(v.out_of_range) + '}';
  c = Cursor::PerEngine{v.torque.total(), v.incycle.total(), v.cylinder_version, v.status_version,
                        v.crank_version};
}

std::string Model::delta(Cursor& c) const {
  const bool fresh = !c.snapshot_sent;
  bool changed = fresh;
  for (const auto& [id, v] : engines_) {
    const auto it = c.engines.find(id);
    if (it == c.engines.end() || it->second.torque != v.torque.total() ||
        it->second.incycle != v.incycle.total() || it->second.status != v.status_version ||
        it->second.cylinder != v.cylinder_version || it->second.crank != v.crank_version)
      changed = true;
  }
  if (!changed) return {};
  std::string out = fresh ? "{\"type\":\"snapshot\"," : "{\"type\":\"delta\",";
  if (fresh) {
    append_geometry(out, geometry_);
    out += "\"methods\":" + methods_json() + ',';
  }
  out += "\"engines\":{";
  bool first = true;
  for (const auto& [id, v] : engines_) {
    if (!first) out += ',';
    first = false;
    append_engine(out, id, v, c.engines[id]);
  }
  out += "}}";
  c.snapshot_sent = true;
  return out;
}

}  // namespace torqued::dash
