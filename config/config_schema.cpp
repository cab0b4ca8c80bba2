// The configuration table. Add a key here (one line) and it is parsed, validated, documented and checked
// against config/torqued.example.yaml. Defaults come from the structs (Config{}), so they are written once.
#include "config_schema.hpp"

#include <cmath>
#include <numbers>
#include <span>
#include <sstream>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "schema_builders.hpp"

namespace torqued {

std::string_view can_quantity_name(std::size_t i) noexcept {
  static constexpr std::array<std::string_view, kCanQuantityCount> kNames{
      "map",       "maf",         "intake_temp", "oil_temp",  "throttle",     "lambda", "spark_advance",
      "fuel_mass", "fuel_cutoff", "load_torque", "em_torque", "em_sole_load", "neutral"};
  return i < kNames.size() ? kNames[i] : std::string_view{};
}

namespace {

using namespace schema_detail;

void add_engine(std::vector<SchemaEntry>& t) {
  t.push_back(integer("engine.cylinders", TQ_REF(int, engine.cylinders), closed(1, kMaxCylinders), "",
                      "number of cylinders (4-stroke)"));
  SchemaEntry fo =
      entry("engine.firing_order", ValueKind::kIntList, "", "firing order, a permutation of 1..cylinders");
  apply(fo, closed(1, kMaxCylinders));
  fo.min_len = 1;
  fo.max_len = kMaxCylinders;
  fo.set = [](Config& c, const ConfigValue& v) {
    c.engine.firing_order.fill(0);
    for (std::size_t k = 0; k < v.il.size() && k < kMaxCylinders; ++k)
      c.engine.firing_order[k] = int(v.il[k]);
  };
  fo.get = [](const Config& c) {
    ConfigValue v;
    for (int k = 0; k < c.engine.cylinders && k < kMaxCylinders; ++k)
      v.il.push_back(c.engine.firing_order[k]);
    return v;
  };
  t.push_back(std::move(fo));
  t.push_back(number("engine.bore_m", TQ_REF(double, engine.bore_m), positive(1.0), "m", "cylinder bore"));
  t.push_back(
      number("engine.stroke_m", TQ_REF(double, engine.stroke_m), positive(1.0), "m", "piston stroke = 2R"));
  t.push_back(number("engine.rod_m", TQ_REF(double, engine.rod_m), positive(2.0), "m",
                     "connecting-rod length, must exceed the crank radius stroke/2"));
  t.push_back(number("engine.compression_ratio", TQ_REF(double, engine.compression_ratio),
                     {1.0, 40.0, true, false}, "", "geometric compression ratio r_c"));
  t.push_back(number("engine.j_rot_kgm2", TQ_REF(double, engine.j_rot_kgm2), positive(100.0), "kg m^2",
                     "rotating inertia incl. flywheel and dyno side"));
  t.push_back(number("engine.m_osc_kg", TQ_REF(double, engine.m_osc_kg), closed(0.0, 50.0), "kg",
                     "oscillating mass per cylinder (piston + 1/3 rod)"));
  t.push_back(number("engine.tdc_offset_deg", TQ_REF(double, engine.tdc_offset_rad),
                     {0.0, 720.0, false, true}, "deg",
                     "crank angle of cylinder 1 firing TDC after the first tooth after the gap", kDegToRad));
  t.push_back(number("engine.crankcase_pressure_pa", TQ_REF(double, engine.crankcase_pressure_pa),
                     positive(1e6), "Pa", "crankcase pressure under the pistons"));
}

void add_wheel_decoder(std::vector<SchemaEntry>& t);
void add_wheel_stall_and_cam(std::vector<SchemaEntry>& t);

void add_wheel(std::vector<SchemaEntry>& t) {
  t.push_back(integer("wheel.teeth", TQ_REF(int, wheel.geometry.positions), closed(2, kMaxTeeth), "",
                      "equally spaced tooth positions per revolution incl. missing ones (60 for 60-2)"));
  t.push_back(integer("wheel.missing", TQ_REF(int, wheel.geometry.missing), closed(0, kMaxTeeth), "",
                      "missing teeth in the gap (2 for 60-2), less than teeth"));
  SchemaEntry ta = entry("wheel.tooth_angles_deg", ValueKind::kDoubleList, "deg",
                         "irregular wheels: edge angles in [0,360), increasing; replaces teeth/missing");
  apply(ta, {0.0, 360.0, false, true});
  ta.max_len = kMaxTeeth;
  ta.set = [](Config& c, const ConfigValue& v) {
    auto& w = c.wheel.geometry;
    w.tooth_count = static_cast<int>(std::min<std::size_t>(v.dl.size(), kMaxTeeth));
    w.tooth_angles_deg.fill(0.0);
    for (int k = 0; k < w.tooth_count; ++k)
      w.tooth_angles_deg[static_cast<std::size_t>(k)] = v.dl[std::size_t(k)];
  };
  ta.get = [](const Config& c) {
    ConfigValue v;
    const auto& w = c.wheel.geometry;
    v.dl.assign(w.tooth_angles_deg.begin(), w.tooth_angles_deg.begin() + w.tooth_count);
    return v;
  };
  t.push_back(std::move(ta));
  t.push_back(choice<bool>("wheel.edge", TQ_REF(bool, wheel.geometry.rising_edge),
                           {{"rising", true}, {"falling", false}}, "crank-signal edge that marks a tooth"));
  t.push_back(text("wheel.crank_channel", TQ_REF(std::string, wheel.crank_channel),
                   "edge CSV column name of the crank sensor"));
  t.push_back(text("wheel.cam_channel", TQ_REF(std::string, wheel.cam_channel),
                   "edge CSV column name of the cam sensor (\"\" = none: no 720 deg phase)"));
  t.push_back(choice<bool>("wheel.cam_edge", TQ_REF(bool, wheel.cam_rising_edge),
                           {{"rising", true}, {"falling", false}},
                           "cam-signal edge that marks the 720 deg phase"));
  add_wheel_decoder(t);
  add_wheel_stall_and_cam(t);
}

void add_wheel_decoder(std::vector<SchemaEntry>& t) {
  const std::string d = "wheel.decoder.";
  auto dn = [&](const char* key, double DecoderParams::*m, Bounds b, const char* desc) {
    SchemaEntry e = entry(d + key, ValueKind::kDouble, "", desc);
    apply(e, b);
    e.set = [m](Config& c, const ConfigValue& v) { c.wheel.decoder.*m = v.d; };
    e.get = [m](const Config& c) {
      ConfigValue v;
      v.d = c.wheel.decoder.*m;
      return v;
    };
    t.push_back(std::move(e));
  };
  dn("gap_ratio_min", &DecoderParams::gap_ratio_min, positive(10.0),
     "gap accepted down to this x nominal gap ratio (cranking squeeze)");
  dn("gap_ratio_max", &DecoderParams::gap_ratio_max, positive(100.0), "and up to this x nominal gap ratio");
  dn("sync_ratio_min", &DecoderParams::sync_ratio_min, positive(1.0),
     "synced: period/expected accepted down to this");
  dn("sync_ratio_max", &DecoderParams::sync_ratio_max, {1.0, 10.0, false, false},
     "synced: period/expected accepted up to this");
  dn("runt_fraction", &DecoderParams::runt_fraction, {0.0, 1.0, false, true},
     "synced: edge earlier than this x expected one-pitch period is noise");
  dn("syncing_runt_fraction", &DecoderParams::syncing_runt_fraction, {0.0, 1.0, false, true},
     "syncing: edge earlier than this x predicted period is noise");
  {
    SchemaEntry mp = entry(d + "min_pulse_us", ValueKind::kDouble, "us",
                           "debounce: a crank pulse narrower than this is a glitch, both edges dropped (0 = "
                           "off; on: a tooth is reported at the opposite edge)");
    apply(mp, closed(0.0, 1000.0));
    mp.set = [](Config& c, const ConfigValue& v) { c.wheel.decoder.min_pulse_us = v.d; };
    mp.get = [](const Config& c) {
      ConfigValue v;
      v.d = c.wheel.decoder.min_pulse_us;
      return v;
    };
    t.push_back(std::move(mp));
  }
  t.push_back(integer(d + "burst_teeth", TQ_REF(int, wheel.decoder.burst_teeth), closed(0, kMaxTeeth),
                      "teeth",
                      "synced: after a noise edge this many teeth count as inside a noise burst (0 = off)"));
  dn("burst_tooth_ratio_min", &DecoderParams::burst_tooth_ratio_min, {0.0, 1.0, true, true},
     "noise burst: a period below this x the running tooth period is a glitch (synced); a synced tooth below "
     "x of both the running period and the trend prediction is suspect, and the next edge is noise if the "
     "two "
     "periods make one tooth within [x, 1/x] of both; resyncing after a loss, the run before a gap must lie "
     "within [x, 1/x] of its median and the gap fit it");
  dn("lost_tooth_min_ratio", &DecoderParams::lost_tooth_min_ratio, {1.0, 10.0, false, false},
     "lost-tooth hypothesis only above this period ratio");
  dn("max_trend", &DecoderParams::max_trend, {1.0, 10.0, false, false},
     "period trend clamped to [1/x, x] when predicting the next period (cranking ripple)");
  dn("lost_tooth_min_rpm", &DecoderParams::lost_tooth_min_rpm, closed(0.0, 20000.0),
     "below this speed (rpm) a long period is a slowdown, never a lost tooth");
  t.push_back(integer(d + "max_lost_teeth_per_rev", TQ_REF(int, wheel.decoder.max_lost_teeth_per_rev),
                      closed(0, kMaxTeeth), "", "more lost teeth than this in one revolution = lost sync"));
}

void add_wheel_stall_and_cam(std::vector<SchemaEntry>& t) {
  const std::string d = "wheel.decoder.";
  SchemaEntry stall =
      entry(d + "stall_timeout_s", ValueKind::kDouble, "s", "no crank edge for this long = stalled");
  apply(stall, positive(60.0));
  stall.set = [](Config& c, const ConfigValue& v) {
    c.wheel.decoder.stall_timeout_ns = static_cast<std::int64_t>(std::llround(v.d * 1e9));
  };
  stall.get = [](const Config& c) {
    ConfigValue v;
    v.d = static_cast<double>(c.wheel.decoder.stall_timeout_ns) * 1e-9;
    return v;
  };
  t.push_back(std::move(stall));
  t.push_back(number(d + "cam_window_start_deg", TQ_REF(double, wheel.decoder.cam_window_start_deg),
                     {0.0, 720.0, false, true}, "deg",
                     "cam edge must fall in [start, end) of the 720 deg cycle"));
  t.push_back(number(d + "cam_window_end_deg", TQ_REF(double, wheel.decoder.cam_window_end_deg),
                     {0.0, 720.0, true, false}, "deg", "end of the cam window, > start"));
  t.push_back(choice<bool>(d + "cam_window", TQ_REF(bool, wheel.decoder.cam_window_auto),
                           {{"fixed", false}, {"auto", true}},
                           "fixed: the cam edge must fall in [cam_window_start_deg, cam_window_end_deg); "
                           "auto: learn the cam edge's angle from the first synced cycles (its revolution = "
                           "the first of the cycle) and use +-90 deg around it"));
  t.push_back(integer(d + "cam_auto_edges", TQ_REF(int, wheel.decoder.cam_auto_edges), closed(1, 100), "",
                      "cam_window auto: consistent cam edges needed to learn the cam angle"));
  t.push_back(number(d + "cam_auto_spread_deg", TQ_REF(double, wheel.decoder.cam_auto_spread_deg),
                     {0.0, 90.0, false, true}, "",
                     "cam_window auto: learning cam edges must agree within this (crank deg)"));
}

void add_inputs(std::vector<SchemaEntry>& t) {
  t.push_back(choice<EdgeBackend>(
      "inputs.edges.backend", TQ_REF(EdgeBackend, inputs.edges.backend),
      {{"file", EdgeBackend::kFile}, {"gpio", EdgeBackend::kGpio}, {"can_encoder", EdgeBackend::kCanEncoder}},
      "where crank/cam edges come from"));
  t.push_back(text("inputs.edges.path", TQ_REF(std::string, inputs.edges.path),
                   "edge capture file (backend file); relative to this YAML file", true));
  t.push_back(choice<EdgeFormat>("inputs.edges.format", TQ_REF(EdgeFormat, inputs.edges.format),
                                 {{"csv", EdgeFormat::kCsv}, {"list", EdgeFormat::kList}},
                                 "csv = logic-analyzer export, list = one edge time (s) per line"));
  t.push_back(text("inputs.edges.gpio_chip", TQ_REF(std::string, inputs.edges.gpio_chip),
                   "GPIO chip (backend gpio)"));
  t.push_back(number("inputs.edges.timeout_s", TQ_REF(double, inputs.edges.timeout_s),
                     {0.001, 3600.0, false, false}, "s",
                     "no crank edge for this long = DaemonStatus EDGE_TIMEOUT"));
  t.push_back(integer("inputs.edges.gpio_crank_line", TQ_REF(int, inputs.edges.gpio_crank_line),
                      closed(0, 1023), "", "GPIO line offset of the crank sensor"));
  t.push_back(integer("inputs.edges.gpio_cam_line", TQ_REF(int, inputs.edges.gpio_cam_line), closed(-1, 1023),
                      "", "GPIO line offset of the cam sensor (-1 = none)"));
  t.push_back(integer("inputs.edges.encoder_can_id", TQ_REF(std::uint32_t, inputs.edges.encoder_can_id),
                      closed(0, 0x1FFFFFFF), "",
                      "CAN id of the encoder's tooth-timestamp frames (backend can_encoder)"));
  t.push_back(choice<CanBackend>("inputs.can.backend", TQ_REF(CanBackend, inputs.can.backend),
                                 {{"file", CanBackend::kFile}, {"socketcan", CanBackend::kSocketCan}},
                                 "where CAN frames come from"));
  t.push_back(text("inputs.can.path", TQ_REF(std::string, inputs.can.path),
                   "candump -l log (backend file; \"\" = no CAN input); relative to this YAML file", true));
  t.push_back(text("inputs.can.interface", TQ_REF(std::string, inputs.can.interface),
                   "SocketCAN interface (backend socketcan; also carries can_encoder frames)"));
  t.push_back(boolean("inputs.can.fd", TQ_REF(bool, inputs.can.fd), "accept CAN FD frames"));
  t.push_back(number("inputs.can.time_offset_s", TQ_REF(double, inputs.can.time_offset_s),
                     closed(-1e10, 1e10), "s", "added to CAN timestamps to put them on the edge clock"));
  t.push_back(
      number("inputs.max_time_jump_s", TQ_REF(double, inputs.max_time_jump_s), closed(0.001, 1e6), "s",
             "file inputs: an edge or frame this far ahead of the previous one is dropped as an outlier "
             "(file:line in the log) unless inputs.time_rebase_records records in step follow it"));
  t.push_back(integer("inputs.time_rebase_records", TQ_REF(int, inputs.time_rebase_records), closed(1, 32),
                      "",
                      "file inputs: records in step after a time jump that make it a genuine clock jump "
                      "(re-based, nothing dropped)"));
}

void add_can(std::vector<SchemaEntry>& t) {
  t.push_back(text("can.dbc", TQ_REF(std::string, can.dbc),
                   "DBC file describing the CAN signals (\"\" = none)", true));
  for (std::size_t q = 0; q < kCanQuantityCount; ++q) {
    const std::string base = "can.signals." + std::string(can_quantity_name(q));
    SchemaEntry m = text(base + ".message", nullptr, "DBC message (BO_) carrying it (\"\" = not mapped)");
    m.set = [q](Config& c, const ConfigValue& v) { c.can.signals[q].message = v.s; };
    m.get = [q](const Config& c) {
      ConfigValue v;
      v.s = c.can.signals[q].message;
      return v;
    };
    SchemaEntry s = text(base + ".signal", nullptr, "DBC signal (SG_) name; its DBC unit is converted to SI");
    s.set = [q](Config& c, const ConfigValue& v) { c.can.signals[q].signal = v.s; };
    s.get = [q](const Config& c) {
      ConfigValue v;
      v.s = c.can.signals[q].signal;
      return v;
    };
    SchemaEntry to = entry(base + ".timeout_ms", ValueKind::kInt, "ms", "value older than this is invalid");
    apply(to, closed(1, 60000));
    to.set = [q](Config& c, const ConfigValue& v) { c.can.signals[q].timeout_ms = int(v.i); };
    to.get = [q](const Config& c) {
      ConfigValue v;
      v.i = c.can.signals[q].timeout_ms;
      return v;
    };
    t.push_back(std::move(m));
    t.push_back(std::move(s));
    t.push_back(std::move(to));
  }
  // Hybrid input (estimators/core/e_machine.hpp): used only when can.signals.em_torque is mapped.
  t.push_back(number("can.e_machine.ratio", TQ_REF(double, can.e_machine.ratio), {0.0, 100.0, true, false},
                     "",
                     "machine speed / crank speed: machine torque on the crank = sign x ratio x em_torque"));
  t.push_back(integer(
      "can.e_machine.sign", TQ_REF(int, can.e_machine.sign), closed(-1, 1), "",
      "+1: em_torque positive when the machine drives the crank (motoring/boost), -1: when it brakes it"));
  t.push_back(boolean(
      "can.e_machine.sole_load", TQ_REF(bool, can.e_machine.sole_load),
      "the machine is the only load on the crank (bench motoring, clutch open): no load_torque needed; "
      "can.signals.em_sole_load, when mapped, decides this cycle by cycle instead"));
  // Vehicle load references (estimators/core/load_reference.hpp): used only when em_sole_load or neutral is
  // mapped.
  t.push_back(number(
      "can.load_reference.accessory_nm", TQ_REF(double, can.load_reference.accessory_nm), closed(-50.0, 50.0),
      "N m",
      "prior mean of the accessories' torque (alternator, pumps) while the clutch is open / in neutral "
      "(vehicle flags mapped)"));
  t.push_back(number(
      "can.load_reference.accessory_sd_nm", TQ_REF(double, can.load_reference.accessory_sd_nm),
      closed(0.0, 50.0), "N m",
      "1 sigma of that prior: the uncertainty a clutch-open / neutral reference carries into the learners"));
  t.push_back(number("can.load_reference.fuel_max_sd_nm", TQ_REF(double, can.load_reference.fuel_max_sd_nm),
                     positive(1e3), "N m",
                     "the fuel model learns only from load references at most this uncertain (1 sigma)"));
  // Free coast-down without a flag (chain/angle_pipeline.cpp detect_free_coast; docs/angle_pipeline.md).
  t.push_back(boolean(
      "can.load_reference.free_coast", TQ_REF(bool, can.load_reference.free_coast),
      "with no clutch / neutral / machine flag and no load signal: recognise a fuel cut-off in which the "
      "engine coasts alone (clutch open) from the crank and the fuel, and learn friction from it with the "
      "accessory prior as its load"));
  t.push_back(
      number("can.load_reference.free_coast_step_min", TQ_REF(double, can.load_reference.free_coast_step_min),
             closed(0.0, 10.0), "-",
             "smallest step of the crank's deceleration torque at cut-off entry, as a fraction of the "
             "modelled indicated-torque drop, for a free coast (in gear the vehicle's inertia, >= 2 "
             "engine inertias in any gear, makes it <= 0.33)"));
  t.push_back(number("can.load_reference.free_coast_step_max",
                     TQ_REF(double, can.load_reference.free_coast_step_max), closed(0.0, 10.0), "-",
                     "largest such step (the fuel prior's and friction's error allowed above 1)"));
  t.push_back(number("can.load_reference.free_coast_decel_min",
                     TQ_REF(double, can.load_reference.free_coast_decel_min), closed(0.0, 10.0), "-",
                     "smallest ratio of a free coast's deceleration torque (J theta'') to the free engine's "
                     "(motored torque - prior friction - accessories), checked every cut-off cycle"));
  t.push_back(number("can.load_reference.free_coast_decel_max",
                     TQ_REF(double, can.load_reference.free_coast_decel_max), closed(0.0, 10.0), "-",
                     "largest such ratio (the friction prior's spread across engines allowed)"));
  t.push_back(
      number("can.load_reference.free_coast_decel_change",
             TQ_REF(double, can.load_reference.free_coast_decel_change), closed(0.0, 10.0), "-",
             "largest change of a free coast's deceleration torque from one cycle to the next, as a "
             "fraction of it (friction and pumping move a few per cent per cycle; a dynamometer holding "
             "speed, or a driveline taking up its share, far more): beyond it the coast ends"));
  t.push_back(
      number("can.load_reference.free_coast_idle_map_rise_kpa",
             TQ_REF(double, can.load_reference.free_coast_idle_map_rise_kpa), closed(0.0, 200.0), "kPa",
             "a free coast that ends in idle stays a reference (clutch still open) until MAP rises this "
             "much above its value when the fuel came back, or the speed above idle"));
}

void add_topic_qos(std::vector<SchemaEntry>& t, const std::string& name, Ref<TopicQos> ref) {
  const std::string base = "dds.qos." + name;
  SchemaEntry rel = choice<Reliability>(
      base + ".reliability", nullptr,
      {{"reliable", Reliability::kReliable}, {"best_effort", Reliability::kBestEffort}}, "DDS reliability");
  rel.set = [ref](Config& c, const ConfigValue& v) {
    ref(c).reliability = v.s == "best_effort" ? Reliability::kBestEffort : Reliability::kReliable;
  };
  rel.get = [ref](const Config& c) {
    ConfigValue v;
    v.s = ref(mut(c)).reliability == Reliability::kReliable ? "reliable" : "best_effort";
    return v;
  };
  t.push_back(std::move(rel));
  auto field = [&](const char* key, int TopicQos::*m, Bounds b, const char* unit, const char* desc) {
    SchemaEntry e = entry(base + "." + key, ValueKind::kInt, unit, desc);
    apply(e, b);
    e.set = [ref, m](Config& c, const ConfigValue& v) { ref(c).*m = int(v.i); };
    e.get = [ref, m](const Config& c) {
      ConfigValue v;
      v.i = ref(mut(c)).*m;
      return v;
    };
    t.push_back(std::move(e));
  };
  field("history_depth", &TopicQos::history_depth, closed(1, 10000), "samples", "KEEP_LAST history depth");
  field("deadline_ms", &TopicQos::deadline_ms, closed(0, 3600000), "ms", "offered deadline (0 = none)");
  field("lease_ms", &TopicQos::lease_ms, closed(0, 3600000), "ms",
        "automatic liveliness lease (0 = infinite)");
}

void add_dds(std::vector<SchemaEntry>& t) {
  t.push_back(integer("dds.domain_id", TQ_REF(int, dds.domain_id), closed(0, 232), "", "DDS domain id"));
  t.push_back(
      text("dds.topic_prefix", TQ_REF(std::string, dds.topic_prefix), "topic names are <prefix>/<Type>"));
  t.push_back(integer("dds.engine_id", TQ_REF(int, dds.engine_id), closed(0, 65535), "",
                      "key of every published sample"));
  add_topic_qos(t, "engine_torque", TQ_REF(TopicQos, dds.engine_torque));
  add_topic_qos(t, "estimator_torque", TQ_REF(TopicQos, dds.estimator_torque));
  add_topic_qos(t, "cylinder_torque", TQ_REF(TopicQos, dds.cylinder_torque));
  add_topic_qos(t, "crank_state", TQ_REF(TopicQos, dds.crank_state));
  add_topic_qos(t, "status", TQ_REF(TopicQos, dds.status));
  t.push_back(integer("dds.crank_state_decimation", TQ_REF(int, dds.crank_state_decimation),
                      closed(1, 100000), "teeth", "publish CrankState every n-th tooth"));
  t.push_back(integer("dds.time_estimator_decimation", TQ_REF(int, dds.time_estimator_decimation),
                      closed(1, 100000), "steps",
                      "publish the time methods' EstimatorTorque every n-th time-pipeline step"));
  t.push_back(integer("dds.tooth_estimator_decimation", TQ_REF(int, dds.tooth_estimator_decimation),
                      closed(0, 100000), "teeth",
                      "publish the in-cycle Kalman/Fourier EstimatorTorque every n-th tooth (0 = off)"));
  t.push_back(number("dds.status_period_s", TQ_REF(double, dds.status_period_s), {0.01, 60.0, false, false},
                     "s", "DaemonStatus and sd_notify STATUS= period"));
}

void add_thread(std::vector<SchemaEntry>& t, const std::string& name, Ref<ThreadConfig> ref,
                const std::string& what) {
  const std::string base = "realtime." + name;
  SchemaEntry pol = choice<SchedPolicy>(base + ".policy", nullptr,
                                        {{"fifo", SchedPolicy::kFifo}, {"other", SchedPolicy::kOther}},
                                        "scheduling policy of the " + what);
  pol.set = [ref](Config& c, const ConfigValue& v) {
    ref(c).policy = v.s == "other" ? SchedPolicy::kOther : SchedPolicy::kFifo;
  };
  pol.get = [ref](const Config& c) {
    ConfigValue v;
    v.s = ref(mut(c)).policy == SchedPolicy::kFifo ? "fifo" : "other";
    return v;
  };
  t.push_back(std::move(pol));
  SchemaEntry pr =
      entry(base + ".priority", ValueKind::kInt, "", "SCHED_FIFO priority (1..99; 0 only with policy other)");
  apply(pr, closed(0, 99));
  pr.set = [ref](Config& c, const ConfigValue& v) { ref(c).priority = int(v.i); };
  pr.get = [ref](const Config& c) {
    ConfigValue v;
    v.i = ref(mut(c)).priority;
    return v;
  };
  t.push_back(std::move(pr));
  SchemaEntry cpus = cpu_list(base + ".cpus", nullptr, "CPU affinity list ([] = any CPU)");
  cpus.set = [ref](Config& c, const ConfigValue& v) { ref(c).cpus.assign(v.il.begin(), v.il.end()); };
  cpus.get = [ref](const Config& c) {
    ConfigValue v;
    v.il.assign(ref(mut(c)).cpus.begin(), ref(mut(c)).cpus.end());
    return v;
  };
  t.push_back(std::move(cpus));
}

void add_rest(std::vector<SchemaEntry>& t) {
  add_thread(t, "angle", TQ_REF(ThreadConfig, realtime.angle), "angle pipeline thread (per tooth)");
  add_thread(t, "time", TQ_REF(ThreadConfig, realtime.time), "time pipeline thread (timer)");
  add_thread(t, "source", TQ_REF(ThreadConfig, realtime.source), "source threads (edges, CAN)");
  add_thread(t, "publisher", TQ_REF(ThreadConfig, realtime.publisher), "DDS publisher thread");
  t.push_back(boolean("realtime.lock_memory", TQ_REF(bool, realtime.lock_memory),
                      "mlockall before the threads start"));
  t.push_back(
      boolean("realtime.lock_on_fault", TQ_REF(bool, realtime.lock_on_fault),
              "mlockall with MCL_ONFAULT: pages are locked when first touched instead of every mapped page "
              "at once (the real-time threads' stacks and rings are prefaulted at start; keeps mappings "
              "never touched, e.g. iceoryx's 66 MB management segment with shared memory, out of RSS; "
              "a page first touched later costs one minor fault)"));
  t.push_back(boolean("realtime.require_rt", TQ_REF(bool, realtime.require_rt),
                      "refuse to start when SCHED_FIFO/mlockall are not permitted (else warn)"));
  t.push_back(
      integer("realtime.publisher_spin_us", TQ_REF(int, realtime.publisher_spin_us), closed(0, 10000), "us",
              "paced replay: the publisher wakes at the next edge's due time and polls for its samples this "
              "long instead of waiting to be woken (one thread wake-up less per sample; 0 = off)"));
  t.push_back(text("output.record_dir", TQ_REF(std::string, output.record_dir),
                   "write estimate CSVs into this directory (\"\" = off); relative to this YAML file", true));
  t.push_back(text("output.state_dir", TQ_REF(std::string, output.state_dir),
                   "learned state (friction, tooth corrections); relative to this YAML file", true));
  t.push_back(
      text("output.table_dir", TQ_REF(std::string, output.table_dir),
           "start-up tables (Kalman periodic gains, load RLS integrals) cached per engine, wheel and "
           "parameter set (learned/table_store.hpp): \"\" = <state_dir>/tables, without a state "
           "directory $XDG_CACHE_HOME/torqued or ~/.cache/torqued; \"off\" = computed at every start"));
  t.push_back(choice<ReplayMode>(
      "replay.mode", TQ_REF(ReplayMode, replay.mode),
      {{"fast", ReplayMode::kFast}, {"paced", ReplayMode::kPaced}},
      "file replay as fast as possible (deterministic) or keeping the recording's timing"));
  // Lower bound: a speed like 1e-300 made every due time infinite (undefined conversion, then a paced replay
  // running flat out); 0.001 is a 20 s recording in 5.6 h.
  t.push_back(number("replay.speed", TQ_REF(double, replay.speed), closed(0.001, 1000.0), "x",
                     "paced replay speed factor"));
  t.push_back(choice<FastThreads>(
      "replay.fast_threads", TQ_REF(FastThreads, replay.fast_threads),
      {{"auto", FastThreads::kAuto}, {"1", FastThreads::kOne}, {"3", FastThreads::kThree}},
      "threads of the fast replay: 1 = all on one thread (suits a one-CPU container or a busy shared "
      "machine, where a descheduled helper stalls the chain); 3 = inputs read on a reader thread and the "
      "recording written on a writer thread beside the chain's; auto = 3 when the process may run on at "
      "least 2 CPUs (sched_getaffinity), else 1. Same output either way"));
  t.push_back(
      boolean("replay.exit_when_done", TQ_REF(bool, replay.exit_when_done),
              "paced replay of files that does not loop (replay.loop false): exit (status 0) once the "
              "recording is consumed; false: keep running in a steady done state (every DaemonStatus has "
              "REPLAY_DONE; the ended input does not degrade health). --exit-when-done forces it on"));
  t.push_back(
      boolean("replay.loop", TQ_REF(bool, replay.loop),
              "paced replay of files: start the recording again at its end, times shifted by its length "
              "(never done; the decoder resyncs once per loop); ignored by fast replay and live inputs"));
  t.push_back(boolean("metrics.enabled", TQ_REF(bool, metrics.enabled),
                      "serve Prometheus metrics (text exposition format) on metrics.address at /metrics"));
  t.push_back(text("metrics.address", TQ_REF(std::string, metrics.address),
                   "HOST:PORT of the metrics endpoint (loopback by default; 0.0.0.0:PORT exposes it on every "
                   "interface)"));
  t.push_back(choice<LogLevel>("logging.level", TQ_REF(LogLevel, logging.level),
                               {{"trace", LogLevel::kTrace},
                                {"debug", LogLevel::kDebug},
                                {"info", LogLevel::kInfo},
                                {"warn", LogLevel::kWarn},
                                {"error", LogLevel::kError},
                                {"critical", LogLevel::kCritical},
                                {"off", LogLevel::kOff}},
                               "minimum log level"));
}

std::vector<SchemaEntry> build_schema() {
  std::vector<SchemaEntry> t;
  add_engine(t);
  add_wheel(t);
  add_inputs(t);
  add_can(t);
  add_estimators(t);
  add_dds(t);
  add_rest(t);
  return t;
}

std::string fmt_double(double v) {
  std::ostringstream os;
  os.precision(12);
  os << v;
  std::string s = os.str();
  return s;
}

std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out + "\"";
}

}  // namespace

const std::vector<SchemaEntry>& config_schema() {
  static const std::vector<SchemaEntry> table = build_schema();
  return table;
}

const SchemaEntry* find_schema_entry(const std::string& key) {
  static const std::unordered_map<std::string, const SchemaEntry*> index = [] {
    std::unordered_map<std::string, const SchemaEntry*> m;
    for (const auto& e : config_schema()) m.emplace(e.key, &e);
    return m;
  }();
  auto it = index.find(key);
  return it == index.end() ? nullptr : it->second;
}

bool is_schema_section(const std::string& prefix) {
  // Every proper prefix of a key ("estimators", "estimators.tooth_learn"), built once (the loader asks for
  // each section of every file; a linear scan per question was a tenth of the fuzzed loader's time).
  static const std::unordered_set<std::string> sections = [] {
    std::unordered_set<std::string> s;
    for (const auto& e : config_schema())
      for (std::size_t dot = e.key.find('.'); dot != std::string::npos; dot = e.key.find('.', dot + 1))
        s.insert(e.key.substr(0, dot));
    return s;
  }();
  return sections.count(prefix) != 0;
}

std::string format_config_value(const SchemaEntry& e, const ConfigValue& v) {
  switch (e.kind) {
    case ValueKind::kDouble:
      return fmt_double(v.d);
    case ValueKind::kInt:
      return std::to_string(v.i);
    case ValueKind::kBool:
      return v.b ? "true" : "false";
    case ValueKind::kString:
    case ValueKind::kPath:
      return quote(v.s);
    case ValueKind::kEnum:
      return v.s;
    case ValueKind::kDoubleList: {
      std::string s = "[";
      for (std::size_t k = 0; k < v.dl.size(); ++k) s += (k ? ", " : "") + fmt_double(v.dl[k]);
      return s + "]";
    }
    case ValueKind::kIntList: {
      std::string s = "[";
      for (std::size_t k = 0; k < v.il.size(); ++k) s += (k ? ", " : "") + std::to_string(v.il[k]);
      return s + "]";
    }
  }
  return {};
}

std::string describe_expected(const SchemaEntry& e) {
  std::string what;
  switch (e.kind) {
    case ValueKind::kDouble:
      what = "a finite number";
      break;
    case ValueKind::kInt:
      what = "an integer";
      break;
    case ValueKind::kBool:
      what = "true or false";
      break;
    case ValueKind::kString:
      what = "a string";
      break;
    case ValueKind::kPath:
      what = "a file path";
      break;
    case ValueKind::kEnum: {
      what = "one of ";
      for (std::size_t k = 0; k < e.choices.size(); ++k) what += (k ? "|" : "") + e.choices[k];
      break;
    }
    case ValueKind::kDoubleList:
    case ValueKind::kIntList: {
      what = std::string("a list of ") + (e.kind == ValueKind::kIntList ? "integers" : "finite numbers");
      if (e.min_len == e.max_len && e.min_len > 0)
        what += " with " + std::to_string(e.min_len) + " elements";
      else if (e.max_len > 0)
        what += " with " + std::to_string(e.min_len) + ".." + std::to_string(e.max_len) + " elements";
      break;
    }
  }
  std::vector<std::string> extra;
  if (!e.unit.empty()) extra.push_back(e.unit);
  if (e.bounded) {
    auto num = [&](double x) {
      return e.kind == ValueKind::kInt || e.kind == ValueKind::kIntList
                 ? std::to_string(static_cast<long long>(x))
                 : fmt_double(x);
    };
    std::string r = "range ";
    r += e.lo_open ? "(" : "[";
    r += std::isfinite(e.lo) ? num(e.lo) : "-inf";
    r += ", ";
    r += std::isfinite(e.hi) ? num(e.hi) : "inf";
    r += e.hi_open ? ")" : "]";
    extra.push_back(r);
  }
  if (!extra.empty()) {
    what += " (";
    for (std::size_t k = 0; k < extra.size(); ++k) what += (k ? ", " : "") + extra[k];
    what += ")";
  }
  return what;
}

std::string schema_example_yaml() {
  const Config defaults;
  std::ostringstream os;
  os << "# torqued configuration: every key with its default. Generated from the schema table\n"
        "# (config/config_schema.cpp) by `torqued --print-schema yaml`; relative paths resolve against this "
        "file.\n";
  std::vector<std::string> open;  // currently open section path components
  for (const auto& e : config_schema()) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    for (std::size_t dot; (dot = e.key.find('.', start)) != std::string::npos; start = dot + 1)
      parts.push_back(e.key.substr(start, dot - start));
    const std::string leaf = e.key.substr(start);
    std::size_t common = 0;
    while (common < open.size() && common < parts.size() && open[common] == parts[common]) ++common;
    for (std::size_t k = common; k < parts.size(); ++k) {
      if (k == 0) os << "\n";
      os << std::string(2 * k, ' ') << parts[k] << ":\n";
    }
    open = parts;
    const std::string indent(2 * parts.size(), ' ');
    os << indent << "# " << e.description << "; " << describe_expected(e) << "\n";
    os << indent << leaf << ": " << format_config_value(e, e.get(defaults)) << "\n";
  }
  return os.str();
}

std::string schema_table_text() {
  const Config defaults;
  std::ostringstream os;
  for (const auto& e : config_schema())
    os << e.key << " = " << format_config_value(e, e.get(defaults)) << "  -- " << describe_expected(e) << ": "
       << e.description << "\n";
  return os.str();
}

}  // namespace torqued
