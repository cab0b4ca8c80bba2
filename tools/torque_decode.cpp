// torque-decode: decode an edge capture and/or a candump log to CSV for people to inspect their recordings
// (inspecting recordings, docs/io.md). Streams; progress on a terminal; one-line summary at the end.
//   torque-decode --edges edges.csv [--can can.log --dbc demo.dbc] [--wheel 60-2] [--config torqued.yaml]
//                 --out-teeth teeth.csv --out-can can.csv
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>

#include "backend_factory.hpp"
#include "candump_source.hpp"
#include "cli_exit.hpp"
#include "config_loader.hpp"
#include "crank_decoder.hpp"
#include "dbc.hpp"
#include "edge_file_source.hpp"
#include "replay_merger.hpp"
#include "share_dir.hpp"
#include "wheel_detect.hpp"
#include "wheel_names.hpp"

namespace {

using namespace torqued;

struct Options {
  std::string edges, can, dbc, config, wheel = "60-2", format = "csv", crank = "crank", cam = "cam";
  std::string detect_wheel, out_teeth, out_can, first_row = "levels", out_revs, plot,
                                                plot_script = torqued::tools::share_path("plot_decode.py");
  double can_offset_s = 0.0;
  bool can_offset_given = false;
  bool cam_given = false;  ///< --cam on the command line (not the default column name)
  bool falling = false, quiet = false, revs = false, transitions = false;
};

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (const char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// Per-revolution speed (time from one synced tooth 0 to the next, no sync loss between) and the summary of
/// sync transitions, drained from the decoder's event log after every edge.
struct RevTracker {
  std::int64_t last_t0 = -1;
  std::vector<std::pair<std::int64_t, double>> revs;  ///< (time of the closing tooth 0, rpm)
  std::vector<DecoderEvent> losses, syncs;
  std::uint64_t first_sync_edge = 0;
  void on_tooth(const ToothEvent& t, int teeth_per_rev) {
    if (t.sync != SyncState::kSynced) {
      last_t0 = -1;
      return;
    }
    if (t.tooth % teeth_per_rev != 0) return;
    if (last_t0 >= 0) revs.emplace_back(t.t_ns, 60e9 / static_cast<double>(t.t_ns - last_t0));
    last_t0 = t.t_ns;
  }
};

std::string events_text(std::uint32_t e) {
  std::string s;
  auto add = [&](const char* t) { s += (s.empty() ? "" : "|"), s += t; };
  if (e & kToothNoiseRejected) add("noise");
  if (e & kToothLostRecovered) add("lost_tooth");
  if (e & kToothResynced) add("resync");
  if (e & kToothGap) add("gap");
  return s;
}

/// One RFC 4180 field: quoted (with '"' doubled) when it holds a comma, a quote or a line break. An empty
/// field writes nothing: an empty std::string_view{} has a null data(), which fwrite must not be given (its
/// pointer argument is declared non-null; UBSan stops there).
void csv_field(std::FILE* f, std::string_view v) {
  if (v.empty()) return;
  if (v.find_first_of(",\"\r\n") == std::string_view::npos) {
    std::fwrite(v.data(), 1, v.size(), f);
    return;
  }
  std::fputc('"', f);
  for (const char c : v) {
    if (c == '"') std::fputc('"', f);
    std::fputc(c, f);
  }
  std::fputc('"', f);
}

/// A signal's value at full precision: the exact integer when the signal is an unscaled integer, else the
/// shortest text that reads back as the same double.
std::string value_text(const DbcSignal& s, const std::uint8_t* data, std::size_t len) {
  char buf[40];
  std::to_chars_result r{};
  if (s.value_type == DbcSignal::ValueType::kInteger && s.factor == 1.0 && s.offset == 0.0)
    r = s.is_signed ? std::to_chars(buf, buf + sizeof buf, s.raw(data, len))
                    : std::to_chars(buf, buf + sizeof buf, s.raw_bits(data, len));
  else
    r = std::to_chars(buf, buf + sizeof buf, s.decode(data, len));
  return std::string(buf, r.ptr);
}

/// Buffered CSV file (large stdio buffer; nothing is flushed per line).
struct CsvOut {
  std::FILE* f = nullptr;
  std::unique_ptr<char[]> buf;
  bool open(const std::string& path, const char* header) {
    if (path.empty()) return true;
    f = std::fopen(path.c_str(), "w");
    if (f == nullptr) return false;
    buf = std::make_unique<char[]>(1 << 20);
    std::setvbuf(f, buf.get(), _IOFBF, 1 << 20);
    std::fputs(header, f);
    return true;
  }
  ~CsvOut() {
    if (f != nullptr) std::fclose(f);
  }
};

void print_sync_summary(const CrankDecoder& decoder, const RevTracker& r, const Options& o) {
  const DecoderStats& ds = decoder.stats();
  if (r.syncs.empty()) {
    std::printf("sync: never (%" PRIu64 " crank edges)\n", ds.crank_edges);
  } else {
    std::printf("sync: first at crank edge %" PRIu64 " (%.6f s, tooth %d), syncs %" PRIu64 ", losses %" PRIu64
                ", stalls %" PRIu64 "\n",
                r.first_sync_edge, r.syncs.front().t_ns * 1e-9, r.syncs.front().tooth, ds.syncs,
                ds.sync_losses, ds.stalls);
  }
  for (std::size_t i = 0; i < r.losses.size() && i < 10; ++i) {
    const DecoderEvent& l = r.losses[i];
    const DecoderEvent* back = nullptr;
    for (const auto& s : r.syncs)
      if (s.t_ns > l.t_ns && back == nullptr) back = &s;
    if (back)
      std::printf("  loss at %.6f s: %s, resynced %.3f ms later\n", l.t_ns * 1e-9,
                  to_string(static_cast<SyncLossReason>(l.reason)), (back->t_ns - l.t_ns) * 1e-6);
    else
      std::printf("  loss at %.6f s: %s, not resynced\n", l.t_ns * 1e-9,
                  to_string(static_cast<SyncLossReason>(l.reason)));
  }
  if (r.losses.size() > 10) std::printf("  ... %zu more losses\n", r.losses.size() - 10);
  std::printf("glitches: noise edges %" PRIu64 ", debounced edges %" PRIu64 ", lost teeth %" PRIu64
              ", cam phase errors %" PRIu64 ", width code errors %" PRIu64 "\n",
              ds.noise_edges, ds.debounced_edges, ds.lost_teeth, ds.cam_phase_errors, ds.width_code_errors);
  if (!r.revs.empty()) {
    double lo = 1e300, hi = 0.0, sum = 0.0;
    for (const auto& [t, rpm] : r.revs) {
      lo = std::min(lo, rpm);
      hi = std::max(hi, rpm);
      sum += rpm;
    }
    std::printf("revolutions %zu: rpm per revolution min %.2f, mean %.2f, max %.2f\n", r.revs.size(), lo,
                sum / static_cast<double>(r.revs.size()), hi);
  }
  if (o.revs)
    for (std::size_t i = 0; i < r.revs.size(); ++i)
      std::printf("rev %zu  t %.6f s  %.2f rpm\n", i + 1, r.revs[i].first * 1e-9, r.revs[i].second);
}

bool write_revs(const RevTracker& r, const Options& o) {
  if (o.out_revs.empty()) return true;
  std::FILE* f = std::fopen(o.out_revs.c_str(), "w");
  if (f == nullptr) {
    std::fprintf(stderr, "torque-decode: cannot write %s: %s\n", o.out_revs.c_str(), std::strerror(errno));
    return false;
  }
  std::fputs("t_ns,t_s,rpm\n", f);
  for (const auto& [t, rpm] : r.revs) std::fprintf(f, "%" PRId64 ",%.9f,%.3f\n", t, t * 1e-9, rpm);
  return std::fclose(f) == 0;
}

void add_options(CLI::App& app, Options& o) {
  app.add_option("--edges", o.edges, "edge capture: logic-analyzer CSV (Time [s],crank,cam) or bare list");
  app.add_option("--format", o.format, "edge file format: csv | list")->check(CLI::IsMember({"csv", "list"}));
  app.add_option("--can", o.can, "candump -l log");
  app.add_option("--dbc", o.dbc, "DBC file to decode the CAN frames");
  app.add_option("--wheel", o.wheel, "crank wheel: " + known_wheel_names());
  app.add_option(
      "--detect-wheel", o.detect_wheel,
      "read an unknown wheel off this edge capture (crank column --crank, --falling; cam column --cam if "
      "present): gap structure or repeating tooth pattern, matching catalogue entries, tooth_angles_deg "
      "to paste, speed range (docs/io.md)");
  app.add_flag("--falling", o.falling, "teeth are marked by falling crank edges");
  app.add_option("--crank", o.crank, "crank column name in the edge CSV");
  app.add_option("--cam", o.cam, "cam column name in the edge CSV (\"\" = none)");
  app.add_option(
         "--first-row", o.first_row,
         "edge CSV first row: levels (initial levels, Saleae/sigrok) | edges (every channel starts low, "
         "as rusEFI's reader)")
      ->check(CLI::IsMember({"levels", "edges"}));
  app.add_option("--can-offset", o.can_offset_s,
                 "seconds added to CAN times (e.g. -1700000000 for the demo)");
  app.add_option("--config", o.config,
                 "torqued YAML: wheel, decoder, inputs, DBC from there (other options override paths)");
  app.add_option("--out-teeth", o.out_teeth, "per-tooth CSV output");
  app.add_option("--out-can", o.out_can, "per-signal CAN CSV output (one row per decoded signal)");
  app.add_option("--out-revs", o.out_revs,
                 "per-revolution CSV output: t_ns,t_s,rpm (synced tooth 0 to tooth 0)");
  app.add_flag("--revs", o.revs, "print the per-revolution speed on stdout");
  app.add_flag("--transitions", o.transitions, "print every sync-state transition (debug) on stderr");
  app.add_option("--plot", o.plot,
                 "PNG: speed per tooth with gaps, glitches and sync losses marked (python3-matplotlib)");
  app.add_option(
      "--plot-script", o.plot_script,
      "plot script, run with /usr/bin/python3 (default: plot_decode.py in PREFIX/share/torqued next "
      "to this executable's PREFIX/bin)");
  app.add_flag("-q,--quiet", o.quiet, "no progress display");
  app.footer(
      "Exit status: 0 done; 1 an input could not be read or parsed, or an output not written; 2 command-line "
      "error (unknown option, bad value, file that does not exist, inconsistent options).");
}

/// What is decoded, opened from --config or from the individual options.
struct Inputs {
  WheelGeometry wheel;
  DecoderParams params;
  std::unique_ptr<EdgeSource> edges;
  std::unique_ptr<CanSource> can;
  std::optional<DbcDatabase> dbc;
  std::int64_t can_offset_ns = 0;
  std::string err;  ///< a DBC parse error (reported only if no database could be built)
};

int fail(int status, const std::string& msg) {
  std::fprintf(stderr, "torque-decode: %s\n", msg.c_str());
  return status;
}

/// Returns 0, or the exit status after printing why.
int open_from_config(const Options& o, Inputs& in) {
  LoadResult lr = load_config(o.config);
  if (!lr.ok()) {
    for (const auto& e : lr.errors) std::fprintf(stderr, "%s\n", e.c_str());
    return 1;
  }
  Config cfg = *lr.config;
  if (!o.edges.empty()) cfg.inputs.edges.path = o.edges;
  if (!o.can.empty()) cfg.inputs.can.path = o.can;
  if (!o.dbc.empty()) cfg.can.dbc = o.dbc;
  in.wheel = cfg.wheel.geometry;
  in.params = decoder_params(cfg);
  if (!cfg.inputs.edges.path.empty() || cfg.inputs.edges.backend != EdgeBackend::kFile) {
    in.edges = make_edge_source(cfg, &in.err);
    if (!in.edges) return fail(1, in.err);
  }
  in.can = make_can_source(cfg, &in.err);
  if (!in.can && !in.err.empty()) return fail(1, in.err);
  in.dbc = load_dbc(cfg, &in.err);
  if (!o.can_offset_given) in.can_offset_ns = can_time_offset_ns(cfg);
  return 0;
}

std::unique_ptr<EdgeSource> open_edge_file(const Options& o, std::string& err) {
  if (o.format == "csv") {
    EdgeCsvOptions eo;
    eo.crank_column = o.crank;
    eo.cam_column = o.cam;
    if (o.first_row == "edges") eo.first_row = EdgeCsvFirstRow::kEdgesFromLow;
    auto s = std::make_unique<EdgeCsvSource>(o.edges, eo);
    if (!s->ok()) err = s->last_error();
    return s;
  }
  EdgeListOptions lo;
  lo.level = o.falling ? 0 : 1;
  auto s = std::make_unique<EdgeListSource>(o.edges, lo);
  if (!s->ok()) err = s->last_error();
  return s;
}

/// Returns 0, or the exit status after printing why.
int open_from_options(const Options& o, Inputs& in) {
  if (!trigger_from_name(o.wheel, in.wheel, in.params, &in.err)) return fail(2, in.err);
  if (o.falling) in.wheel.rising_edge = false;  // pattern wheels set the edge their angles refer to
  in.params.use_cam = !o.cam.empty();
  if (!o.edges.empty()) {
    in.edges = open_edge_file(o, in.err);
    if (!in.err.empty()) return fail(1, in.err);
  }
  if (!o.can.empty()) {
    auto s = std::make_unique<CandumpSource>(o.can);
    if (!s->ok()) return fail(1, s->last_error());
    in.can = std::move(s);
  }
  if (!o.dbc.empty()) {
    DbcParseResult r = DbcDatabase::parse_file(o.dbc);
    if (!r.db) return fail(1, r.errors.empty() ? o.dbc + ": cannot read" : r.errors.front());
    for (const auto& e : r.errors) std::fprintf(stderr, "torque-decode: %s\n", e.c_str());  // each skipped
    in.dbc = std::move(r.db);
  }
  return 0;
}

/// --detect-wheel: the marking crank edges of the capture, then the wheel they show.
int detect_wheel_main(Options o) {
  o.edges = o.detect_wheel;
  std::string err;
  auto src = open_edge_file(o, err);  // with the cam column (--cam) when the capture has it
  if (!err.empty()) {
    const std::string cam_err = err, cam_name = o.cam;
    err.clear();
    o.cam = "";
    src = open_edge_file(o, err);
    if (err.empty() && o.cam_given)  // it reads without the cam: say that the asked-for cam column is dropped
      std::fprintf(stderr, "torque-decode: note: --cam %s dropped (%s); reading the crank alone\n",
                   shell_quote(cam_name).c_str(), cam_err.c_str());
  }
  if (!err.empty()) return fail(1, err);
  std::vector<std::int64_t> teeth, other;  // marking edges, and the other polarity (pulse widths)
  std::vector<WheelCamEdge> cam;
  EdgeEvent e;
  while (src->next(e) == SourceStatus::kOk) {
    if (e.channel == kCrankChannel) ((e.level != 0) != o.falling ? teeth : other).push_back(e.t_ns);
    if (e.channel != kCrankChannel) cam.push_back({e.t_ns, e.level != 0});
  }
  const WheelDetection d = detect_wheel(teeth, other, cam);
  std::fputs(describe(d).c_str(), d.error.empty() ? stdout : stderr);
  return d.error.empty() ? 0 : 1;
}

/// The decoding loop's outputs and counters.
struct Decoding {
  DecoderEventLog events;
  RevTracker revs;
  CsvOut teeth_csv, can_csv;
  double rpm_min = 1e300, rpm_max = 0;
  std::uint64_t frames_decoded = 0, frames_unknown = 0, frames_bad_dlc = 0;
};

void on_edge(const Options& o, const EdgeEvent& edge, CrankDecoder& decoder, Decoding& d) {
  constexpr double kRadSToRpm = 60.0 / (2.0 * std::numbers::pi);
  ToothEvent tooth;
  const bool got = decoder.on_edge(edge, tooth);
  for (DecoderEvent ev; d.events.pop(ev);) {
    if (o.transitions)
      std::fprintf(
          stderr, "debug: %.9f s %s -> %s: %s%s%s (tooth %d)\n", ev.t_ns * 1e-9, to_string(ev.from),
          to_string(ev.to), to_string(ev.kind), ev.kind == DecoderEventKind::kLost ? " " : "",
          ev.kind == DecoderEventKind::kLost ? to_string(static_cast<SyncLossReason>(ev.reason)) : "",
          ev.tooth);
    if (ev.kind == DecoderEventKind::kLost) d.revs.losses.push_back(ev);
    if (ev.kind == DecoderEventKind::kSynced) {
      if (d.revs.syncs.empty()) d.revs.first_sync_edge = decoder.stats().crank_edges;
      d.revs.syncs.push_back(ev);
    }
  }
  if (!got) return;
  d.revs.on_tooth(tooth, decoder.teeth_per_rev());
  const double rpm = tooth.speed_rad_s * kRadSToRpm;
  if (tooth.sync == SyncState::kSynced) {
    d.rpm_min = std::min(d.rpm_min, rpm);
    d.rpm_max = std::max(d.rpm_max, rpm);
  }
  if (d.teeth_csv.f != nullptr) {
    std::fprintf(d.teeth_csv.f, "%" PRId64 ",%.9f,%d,%.4f,%.2f,%s,%d,%s\n", tooth.t_ns, tooth.t_ns * 1e-9,
                 tooth.tooth,
                 tooth.sync == SyncState::kSynced ? tooth.angle_rad * 180.0 / std::numbers::pi : -1.0, rpm,
                 to_string(tooth.sync), tooth.phase_known ? 1 : 0, events_text(tooth.events).c_str());
  }
}

void on_frame(const CanFrame& f, const std::optional<DbcDatabase>& dbc, Decoding& d) {
  const DbcMessage* m = dbc ? dbc->find(f.id, f.extended) : nullptr;
  if (m == nullptr) {
    ++d.frames_unknown;
    return;
  }
  bool bad = false;
  for (const auto& s : m->signals) {
    if (f.len < s.bytes_needed()) {
      bad = true;
      continue;
    }
    if (!m->signal_present(s, f.data.data(), f.len)) continue;
    if (d.can_csv.f != nullptr) {
      const std::string* label = s.value_name(s.raw(f.data.data(), f.len));
      std::FILE* out = d.can_csv.f;
      std::fprintf(out, "%" PRId64 ",%.6f,%u,0x%X,", f.t_ns, f.t_ns * 1e-9, f.bus, f.id);
      for (const std::string_view v : {std::string_view(m->name), std::string_view(s.name)}) {
        csv_field(out, v);
        std::fputc(',', out);
      }
      std::fputs(value_text(s, f.data.data(), f.len).c_str(), out);
      std::fputc(',', out);
      csv_field(out, s.unit);
      std::fputc(',', out);
      csv_field(out, label ? *label : std::string_view{});
      std::fputc('\n', out);
    }
  }
  bad ? ++d.frames_bad_dlc : ++d.frames_decoded;
}

/// Progress on a terminal only (never in pipes/tests): fraction of input bytes consumed.
struct Progress {
  bool tty = false;
  std::uint64_t total_bytes = 0, n = 0;
  std::chrono::steady_clock::time_point last = std::chrono::steady_clock::now();
  explicit Progress(const Options& o) : tty(!o.quiet && ::isatty(STDERR_FILENO) != 0) {
    std::error_code ec;
    for (const auto* s : {&o.edges, &o.can}) {
      if (!s->empty()) total_bytes += std::filesystem::file_size(*s, ec);
    }
  }
  void tick(const Inputs& in, const CrankDecoder& decoder, const ReplayMerger& merger) {
    if (!tty || (++n & 0xFFFF) != 0) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last <= std::chrono::milliseconds(250) || total_bytes == 0) return;
    last = now;
    const std::uint64_t done =
        (in.edges ? in.edges->stats().bytes : 0) + (in.can ? in.can->stats().bytes : 0);
    std::fprintf(stderr, "\r%5.1f %%  %" PRIu64 " teeth  %" PRIu64 " frames", 100.0 * done / total_bytes,
                 decoder.stats().teeth, merger.frames_out());
  }
  ~Progress() {
    if (tty) std::fprintf(stderr, "\r%60s\r", "");
  }
};

std::uint64_t decode_all(const Options& o, Inputs& in, CrankDecoder& decoder, Decoding& d) {
  Progress progress(o);
  ReplayMerger merger(in.edges.get(), in.can.get(), in.can_offset_ns);
  ReplayMerger::Item item;
  for (;;) {
    const SourceStatus st = merger.next(item);
    if (st == SourceStatus::kEnd) break;
    if (st == SourceStatus::kError) {
      std::fprintf(stderr, "torque-decode: input error: %s %s\n",
                   in.edges ? in.edges->last_error().c_str() : "",
                   in.can ? in.can->last_error().c_str() : "");
      continue;
    }
    if (st != SourceStatus::kOk) continue;
    if (item.kind == ReplayMerger::Kind::kEdge)
      on_edge(o, item.edge, decoder, d);
    else
      on_frame(item.frame, in.dbc, d);
    progress.tick(in, decoder, merger);
  }
  return merger.frames_out();
}

void print_summary(const Inputs& in, const CrankDecoder& decoder, const Decoding& d, std::uint64_t frames) {
  // Bad-line messages (first few of each source), then the one-line summary on stdout.
  auto report = [](const char* what, const std::vector<std::string>& msgs) {
    for (const auto& m : msgs) std::fprintf(stderr, "%s: %s\n", what, m.c_str());
  };
  if (auto* s = dynamic_cast<EdgeCsvSource*>(in.edges.get())) report("bad line", s->bad_line_messages());
  if (auto* s = dynamic_cast<EdgeListSource*>(in.edges.get())) report("bad line", s->bad_line_messages());
  if (auto* s = dynamic_cast<CandumpSource*>(in.can.get())) report("bad line", s->bad_line_messages());
  const DecoderStats& ds = decoder.stats();
  std::printf("edges %" PRIu64 " (crank %" PRIu64 ", cam %" PRIu64 "), teeth %" PRIu64 " (synced %" PRIu64
              "), syncs %" PRIu64 ", sync losses %" PRIu64 " (last: %s), stalls %" PRIu64
              ", noise edges %" PRIu64 ", lost teeth %" PRIu64 ", cam phase errors %" PRIu64
              ", rpm %.0f-%.0f, frames %" PRIu64 " (decoded %" PRIu64 ", unknown id %" PRIu64
              ", bad dlc %" PRIu64 "), bad lines %" PRIu64 " edges / %" PRIu64 " can\n",
              ds.edges, ds.crank_edges, ds.cam_edges, ds.teeth, ds.synced_teeth, ds.syncs, ds.sync_losses,
              to_string(ds.last_loss_reason), ds.stalls, ds.noise_edges, ds.lost_teeth, ds.cam_phase_errors,
              d.rpm_max > 0 ? d.rpm_min : 0.0, d.rpm_max, frames, d.frames_decoded, d.frames_unknown,
              d.frames_bad_dlc, in.edges ? in.edges->stats().bad_lines : 0,
              in.can ? in.can->stats().bad_lines : 0);
}

int run_plot(const Options& o, int teeth_per_rev, bool temp_teeth) {
  const std::string cmd = "/usr/bin/python3 " + shell_quote(o.plot_script) + " --teeth " +
                          shell_quote(o.out_teeth) + " --teeth-per-rev " + std::to_string(teeth_per_rev) +
                          " --out " + shell_quote(o.plot) + " --title " +
                          shell_quote("torque-decode: " + (o.edges.empty() ? o.config : o.edges));
  const int rc = std::system(cmd.c_str());
  std::error_code ec;
  if (temp_teeth) std::filesystem::remove(o.out_teeth, ec);
  if (rc != 0) return fail(1, "plot failed (" + cmd + ")");
  std::printf("plot: %s\n", o.plot.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "torque-decode: decode a crank/cam edge capture and/or a candump log to CSV.\n"
      "Per tooth: time, tooth index in 720 deg, angle, rpm, sync state, events (noise edge, lost tooth, "
      "gap, resync). Per CAN frame: time and every DBC signal by name. Ends with a one-line summary."};
  add_options(app, o);
  TORQUED_CLI_PARSE(app, argc, argv);
  o.can_offset_given = app.count("--can-offset") > 0;
  o.cam_given = app.count("--cam") > 0;

  if (!o.detect_wheel.empty()) return detect_wheel_main(o);
  Inputs in;
  in.can_offset_ns = static_cast<std::int64_t>(std::llround(o.can_offset_s * 1e9));
  if (const int rc = o.config.empty() ? open_from_options(o, in) : open_from_config(o, in); rc != 0)
    return rc;
  if (!in.err.empty() && !in.dbc) return fail(1, in.err);
  if (!in.edges && !in.can) {
    std::fprintf(stderr, "torque-decode: nothing to decode: give --edges and/or --can (or --config)\n%s",
                 app.help().c_str());
    return 2;
  }
  CrankDecoder decoder(in.wheel, in.params);
  if (!decoder.valid()) return fail(2, decoder.error());

  Decoding d;
  decoder.set_event_log(&d.events);
  // The plot reads the per-tooth CSV: without --out-teeth it goes next to the PNG and is removed afterwards.
  const bool temp_teeth = !o.plot.empty() && o.out_teeth.empty();
  if (temp_teeth) o.out_teeth = o.plot + ".teeth.csv";
  if (!d.teeth_csv.open(o.out_teeth, "t_ns,t_s,tooth,angle_deg,rpm,sync,phase_known,events\n") ||
      !d.can_csv.open(o.out_can, "t_ns,t_s,bus,id,message,signal,value,unit,label\n"))
    return fail(1, std::string("cannot write output: ") + std::strerror(errno));

  const std::uint64_t frames = decode_all(o, in, decoder, d);
  print_summary(in, decoder, d, frames);
  print_sync_summary(decoder, d.revs, o);
  if (d.teeth_csv.f != nullptr) std::fflush(d.teeth_csv.f);
  if (!write_revs(d.revs, o)) return 1;
  return o.plot.empty() ? 0 : run_plot(o, decoder.teeth_per_rev(), temp_teeth);
}
