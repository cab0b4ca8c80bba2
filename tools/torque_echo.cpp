// torque-echo: a DDS subscriber (its own process) for the torque topics. Prints samples as a table or JSON
// lines and/or records them to CSV (same columns as the daemon's recorder; the input of torque-eval).
//   torque-echo --topic engine --record out/            live table of per-cycle/segment torque + CSV
//   torque-echo --topic all --format json --count 100   first 100 samples of every topic as JSON lines
//   torque-echo --until-done                            exit when the daemon reports the end of a replay
//   torque-echo --config demo_shm.yaml --require-shm    the daemon's domain/prefix/QoS; exit 4 unless on shm
// It reports on stderr when a topic's writer (the daemon) appears, loses its liveliness (the daemon died or
// hangs: no sign of it within the topic's lease) and when a topic misses its deadline (no sample within the
// topic's deadline period); --exit-on-lost exits with status 3 when the daemon's writers are gone.
// Network hygiene: run with CYCLONEDDS_URI pointing at a loopback-only configuration (config/).
#include <signal.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "cli_exit.hpp"
#include "dds/dds.h"
#include "dds/ddsc/dds_loan_api.h"
#include "dds_from_config.hpp"
#include "methods.hpp"
#include "qos.hpp"
#include "sample.hpp"
#include "sample_recorder.hpp"
#include "topic_format.hpp"

namespace {
volatile sig_atomic_t g_stop = 0;
/// --require-shm refused: exit status 4.
struct RequireShmError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
void on_signal(int) { g_stop = 1; }

using namespace torqued;

/// Printed once under each table's header: what the coded columns mean (idl/torque.idl).
constexpr const char* kHealthCodes =
    "0 valid, 1 not converged, 2 not excited, 3 stale input, 4 invalid input, 5 no sync, 6 numerical, 7 "
    "disabled";
template <class T>
const char* table_legend() {
  if constexpr (std::is_same_v<T, torque_EngineTorque>)
    return "# brake = indicated - friction (N m); fused = best brake estimate, \"=brake\" when it is the "
           "brake value\n"
           "# itself; src = method the fused value relies on most; q = quality (Health of fused: see "
           "below);\n"
           "# valid = validity bits: 0x01 no sync, 0x02 stale CAN, 0x04 not converged, 0x08 estimator "
           "fault,\n"
           "# 0x10 drops upstream (0x00 = fully valid)\n";
  else if constexpr (std::is_same_v<T, torque_CrankState>)
    return "# sync: 0 no signal, 1 syncing, 2 synced, 3 lost sync, 4 stalled; tooth -1 = not synced\n";
  else if constexpr (std::is_same_v<T, torque_DaemonStatus>)
    return "# health: 0 ok, 1 degraded, 2 failed; flags: 0x01 RT not permitted, 0x02 mlock failed, 0x04 edge "
           "time-out,\n"
           "# 0x08 CAN time-out, 0x10 no sync, 0x20 drops, 0x40 replay done, 0x80 draining\n";
  else
    return nullptr;
}

/// EngineTorque row of the live table: as dds::append_table_row, but the fused column says "=brake" when the
/// fused value is the brake value (no second identical column of numbers) and names its source method.
void append_engine_row(std::string& out, const torque_EngineTorque& s) {
  char fused[16], line[200];
  if (s.fused_nm == s.brake_nm)
    std::snprintf(fused, sizeof fused, "%7s", "=brake");
  else
    std::snprintf(fused, sizeof fused, "%7.1f", s.fused_nm);
  const char* src = dds::method_name(s.fused_source);
  std::snprintf(line, sizeof line, "%8.3f %-5s %5u %5.0f %7.1f %7.1f %7.1f %7.1f %s %-13s %2u 0x%02x\n",
                static_cast<double>(s.source_t_ns) * 1e-9, s.kind == torque_KIND_CYCLE ? "cycle" : "seg",
                s.cycle, s.speed_rad_s * 30.0 / 3.141592653589793, s.brake_nm, s.indicated_nm, s.friction_nm,
                s.load_nm, fused, src, unsigned{s.quality}, s.validity);
  out += line;
}
constexpr const char* kEngineHeader =
    "   t [s] kind   cyc  rpm     brake   indic   frict    load   fused src            q valid\n";

struct Options {
  std::vector<std::string> topics{"engine"};
  std::string config;  ///< the daemon's YAML: domain, prefix and per-topic QoS (command line overrides)
  bool domain_given = false, prefix_given = false;
  int history = 1024;  ///< reader keep-last depth per key (more than the writer's: no loss when descheduled)
  bool no_deadline = false;
  bool require_shm = false;
  std::string format = "table";
  std::string record_dir;
  bool cycles_only = false;
  std::uint32_t domain = 0;
  std::string prefix = "torque";
  double duration_s = 0.0;
  std::uint64_t count = 0;
  bool until_done = false;
  bool exit_on_lost = false;
  double idle_exit_s = 0.0;
  bool quiet = false;
  bool fail_on_gaps = false;   ///< exit 5 when a sequence gap was seen
  bool fail_on_range = false;  ///< exit 6 when a sample was outside the configured engine's physical range
};

template <class T>
struct Reader {
  dds_entity_t reader = 0;
  static constexpr int kBatch = 64;
  std::array<T, kBatch> buf{};
  std::array<void*, kBatch> ptrs{};
  std::array<dds_sample_info_t, kBatch> info{};
  bool had_writer = false;  ///< a writer was alive on this topic at some point
  std::uint32_t alive = 0;  ///< writers alive now
};

class Echo {
 public:
  explicit Echo(const Options& o) : o_(o) {
    if (!o.config.empty()) {
      settings_ = tools::dds_settings_from_file(o.config);
      range_ = tools::torque_range_from_file(o.config);
    }
    if (o.config.empty() || o.domain_given) settings_.domain_id = o.domain;
    if (o.config.empty() || o.prefix_given) settings_.topic_prefix = o.prefix;
    // No deadline requested: what iceoryx can carry, and what matches a writer offering none.
    if (o.no_deadline)
      for (auto& q : settings_.qos) q.deadline_ms = 0;
    if (!o.record_dir.empty()) {
      recorder_ = std::make_unique<dds::SampleRecorder>(o.record_dir);
      if (!recorder_->ok()) throw std::runtime_error(recorder_->error());
    }
    participant_ = dds_create_participant(settings_.domain_id, nullptr, nullptr);
    if (participant_ < 0)
      throw std::runtime_error(std::string("dds_create_participant: ") + dds_strretcode(participant_));
    waitset_ = dds_create_waitset(participant_);
    for (const auto& t : o.topics) {
      const bool all = t == "all";
      if (all || t == "engine") make(engine_, dds::Topic::kEngineTorque);
      if (all || t == "estimator") make(estimator_, dds::Topic::kEstimatorTorque);
      if (all || t == "cylinder") make(cylinder_, dds::Topic::kCylinderTorque);
      if (all || t == "crank") make(crank_, dds::Topic::kCrankState);
      if (all || t == "status") make(status_, dds::Topic::kDaemonStatus);
    }
    // The status topic says when a replay is done: --until-done (or printing the status) exits then, and
    // otherwise the deadline checks stop (a finished replay publishes nothing: not a missed deadline). Read
    // even when not printed, except under --require-shm where only what was asked is subscribed.
    exit_on_done_ = o.until_done || status_.reader != 0;
    if (status_.reader == 0 && (o.until_done || !o.require_shm)) {
      make(status_, dds::Topic::kDaemonStatus);
      print_status_ = false;
    }
    report_transport();
  }
  ~Echo() {
    if (recorder_) recorder_->flush(true);
    dds_delete(participant_);
  }

  int run() {
    const auto t0 = std::chrono::steady_clock::now();
    auto last_data = t0;
    while (!g_stop) {
      dds_waitset_wait(waitset_, nullptr, 0, DDS_MSECS(100));
      const std::uint64_t before = received_;
      take(engine_, dds::Topic::kEngineTorque);
      take(estimator_, dds::Topic::kEstimatorTorque);
      take(cylinder_, dds::Topic::kCylinderTorque);
      take(crank_, dds::Topic::kCrankState);
      take(status_, dds::Topic::kDaemonStatus);
      check_health(engine_, dds::Topic::kEngineTorque);
      check_health(estimator_, dds::Topic::kEstimatorTorque);
      check_health(cylinder_, dds::Topic::kCylinderTorque);
      check_health(crank_, dds::Topic::kCrankState);
      check_health(status_, dds::Topic::kDaemonStatus);
      std::fflush(stdout);
      update_lost();
      if (o_.exit_on_lost && lost_) {
        std::fprintf(stderr, "torque-echo: the daemon's writers are gone: exiting (--exit-on-lost)\n");
        return 3;
      }
      const auto now = std::chrono::steady_clock::now();
      if (received_ != before) last_data = now;
      if (o_.count && received_ >= o_.count) break;
      if (done_ && exit_on_done_) break;
      if (o_.duration_s > 0 && std::chrono::duration<double>(now - t0).count() >= o_.duration_s) break;
      if (o_.idle_exit_s > 0 && received_ > 0 &&
          std::chrono::duration<double>(now - last_data).count() >= o_.idle_exit_s)
        break;
    }
    if (!o_.quiet)
      std::fprintf(stderr, "torque-echo: %llu samples received%s\n",
                   static_cast<unsigned long long>(received_),
                   done_ ? " (daemon reported end of replay)" : "");
    const std::uint64_t gaps = report_gaps();
    const std::uint64_t bad = report_out_of_range();
    if (o_.fail_on_gaps && gaps > 0) return 5;
    return o_.fail_on_range && bad > 0 ? 6 : 0;
  }

 private:
  /// Samples lost between two received ones of the same instance (engine, and method for EstimatorTorque):
  /// the writer's seq counts per instance, so a jump of k means k - 1 samples never arrived (a stalled
  /// subscriber whose history overflowed, a lossy network). Said at exit per topic, even with --quiet.
  template <class T>
  void count_gap(const T& s, dds::Topic t) {
    int instance = 0;
    if constexpr (std::is_same_v<T, torque_EstimatorTorque>) instance = s.method;
    std::uint64_t& last = last_seq_[{static_cast<int>(t) * 256 + instance, s.engine_id}];
    if (last != 0 && s.seq > last + 1) gaps_[static_cast<std::size_t>(t)] += s.seq - last - 1;
    if (s.seq > last) last = s.seq;
  }
  /// Samples outside the physical range of the configured engine (dds/physical_range.hpp): counted per
  /// topic, the first one of each topic said at once, their table rows marked "OUT OF RANGE".
  template <class T>
  bool check_range(const T& s, dds::Topic t) {
    if constexpr (std::is_same_v<T, torque_EngineTorque> || std::is_same_v<T, torque_EstimatorTorque>) {
      if (dds::in_range(s, range_)) return true;
      if (out_of_range_[static_cast<std::size_t>(t)]++ == 0) {
        double v = 0.0;
        if constexpr (std::is_same_v<T, torque_EngineTorque>)
          v = s.fused_nm;
        else
          v = s.value_nm;
        std::fprintf(stderr,
                     "torque-echo: %s: engine %u sent a torque outside the physical range of the configured "
                     "engine (|T| <= %.0f N m mean, %.0f N m instantaneous; e.g. %g N m): flagged\n",
                     settings_.topic_name(t).c_str(), unsigned{s.engine_id}, range_.mean_nm,
                     range_.instant_nm, v);
      }
      return false;
    }
    return true;
  }
  std::uint64_t report_out_of_range() const {
    std::uint64_t total = 0;
    for (int i = 0; i < dds::kTopicCount; ++i) {
      const std::uint64_t n = out_of_range_[static_cast<std::size_t>(i)];
      total += n;
      if (n > 0)
        std::fprintf(stderr, "torque-echo: %s: %llu samples outside the engine's physical range\n",
                     settings_.topic_name(static_cast<dds::Topic>(i)).c_str(),
                     static_cast<unsigned long long>(n));
    }
    return total;
  }
  std::uint64_t report_gaps() const {
    std::uint64_t total = 0;
    for (int i = 0; i < dds::kTopicCount; ++i) {
      const std::uint64_t g = gaps_[static_cast<std::size_t>(i)];
      total += g;
      if (g > 0)
        std::fprintf(stderr, "torque-echo: %s: %llu samples missing (sequence gaps)\n",
                     settings_.topic_name(static_cast<dds::Topic>(i)).c_str(),
                     static_cast<unsigned long long>(g));
    }
    return total;
  }

  template <class T>
  void make(Reader<T>& r, dds::Topic t) {
    if (r.reader != 0) return;
    const dds_entity_t topic = dds::create_topic(participant_, settings_, t);
    if (topic < 0)
      throw std::runtime_error("dds_create_topic " + settings_.topic_name(t) + ": " + dds_strretcode(topic));
    dds_qos_t* qos = dds::make_qos(settings_.qos[static_cast<std::size_t>(t)]);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, o_.history);  // more than the writer's depth
    r.reader = dds_create_reader(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    if (r.reader < 0)
      throw std::runtime_error("dds_create_reader " + settings_.topic_name(t) + ": " +
                               dds_strretcode(r.reader));
    for (int i = 0; i < Reader<T>::kBatch; ++i)
      r.ptrs[static_cast<std::size_t>(i)] = &r.buf[static_cast<std::size_t>(i)];
    const dds_entity_t rc = dds_create_readcondition(r.reader, DDS_ANY_STATE);
    dds_waitset_attach(waitset_, rc, r.reader);
    // The reader itself as a status condition: writer liveliness changes and missed deadlines wake us too.
    dds_set_status_mask(r.reader, DDS_LIVELINESS_CHANGED_STATUS | DDS_REQUESTED_DEADLINE_MISSED_STATUS);
    dds_waitset_attach(waitset_, r.reader, r.reader);
    (dds_is_shared_memory_available(r.reader) ? shm_topics_ : net_topics_) += " " + settings_.topic_name(t);
  }

  /// Which readers take their samples from shared memory (iceoryx) and which from the network path; with
  /// --require-shm a reader on the network path is an error (exit status 4), before anything is received.
  void report_transport() const {
    if (!o_.quiet && !shm_topics_.empty())
      std::fprintf(stderr, "torque-echo: shared memory (iceoryx) for:%s\n", shm_topics_.c_str());
    if (o_.require_shm && !net_topics_.empty())
      throw RequireShmError("--require-shm: not on shared memory:" + net_topics_ +
                            " (needs SharedMemory in CYCLONEDDS_URI, RouDi running, and QoS iceoryx carries: "
                            "keep-last, volatile, no deadline: --config with the daemon's shared-memory "
                            "QoS or --no-deadline)");
  }

  /// Writer liveliness and deadline of one topic, reported on stderr (reading the statuses resets them).
  template <class T>
  void check_health(Reader<T>& r, dds::Topic t) {
    if (r.reader == 0) return;
    const std::string name = settings_.topic_name(t);
    const dds::TopicQos& q = settings_.qos[static_cast<std::size_t>(t)];
    dds_liveliness_changed_status_t lc{};
    if (dds_get_liveliness_changed_status(r.reader, &lc) == DDS_RETCODE_OK) {
      r.alive = lc.alive_count;
      if (lc.alive_count > 0) r.had_writer = true;
      if (lc.alive_count_change > 0)
        std::fprintf(stderr, "torque-echo: %s: writer alive (%u alive)\n", name.c_str(), lc.alive_count);
      // A writer that stops being alive: its lease expired (the daemon died, hangs or is unreachable) or it
      // was deleted (the daemon stopped; Cyclone reports that as not-alive too, so the two are one message).
      if (lc.not_alive_count_change > 0 || lc.alive_count_change < 0) {
        std::fprintf(stderr,
                     "torque-echo: %s: writer lost liveliness: the daemon stopped, or showed no sign of life "
                     "within its %lld ms lease (died, hung or unreachable); %u alive\n",
                     name.c_str(), static_cast<long long>(q.lease_ms), lc.alive_count);
      }
    }
    dds_requested_deadline_missed_status_t dm{};
    if (dds_get_requested_deadline_missed_status(r.reader, &dm) == DDS_RETCODE_OK &&
        dm.total_count_change > 0 && !done_)
      std::fprintf(stderr, "torque-echo: %s: deadline missed: no sample within %lld ms (%u times in total)\n",
                   name.c_str(), static_cast<long long>(q.deadline_ms), dm.total_count);
  }

  /// The daemon's writers are gone when every topic that had a live writer has none left. One topic's
  /// loss alone is not enough: the writers share the daemon's lease, but each reader reports its own
  /// loss, and they can arrive one wake-up (100 ms) apart; exiting on the first would hide the others.
  void update_lost() {
    bool any = false, all_gone = true;
    const auto one = [&](const auto& r) {
      if (r.reader == 0 || !r.had_writer) return;
      any = true;
      all_gone = all_gone && r.alive == 0;
    };
    one(engine_);
    one(estimator_);
    one(cylinder_);
    one(crank_);
    one(status_);
    lost_ = any && all_gone;
  }

  template <class T>
  void take(Reader<T>& r, dds::Topic t) {
    if (r.reader == 0) return;
    for (;;) {
      const int n = dds_take(r.reader, r.ptrs.data(), r.info.data(), Reader<T>::kBatch, Reader<T>::kBatch);
      if (n <= 0) return;
      for (int i = 0; i < n; ++i) {
        if (!r.info[static_cast<std::size_t>(i)].valid_data) continue;
        const T& s = r.buf[static_cast<std::size_t>(i)];
        count_gap(s, t);
        const bool plausible = check_range(s, t);
        if constexpr (std::is_same_v<T, torque_DaemonStatus>) {
          if ((s.flags & torque_STATUS_REPLAY_DONE) && !done_) {
            done_ = true;
            if (!o_.quiet && !exit_on_done_)
              std::fprintf(stderr,
                           "torque-echo: the daemon reported the end of its replay: no more samples to come "
                           "(deadline checks off)\n");
          }
          if (!print_status_) continue;
        }
        if constexpr (std::is_same_v<T, torque_EngineTorque>) {
          if (o_.cycles_only && s.kind != torque_KIND_CYCLE) continue;
        }
        ++received_;
        dds::AnySample a;
        a.topic = t;
        std::memcpy(static_cast<void*>(&a.u), &s, sizeof s);
        if (recorder_) recorder_->record(a);
        if (o_.format == "none") continue;
        line_.clear();
        if (o_.format == "json") {
          dds::append_json(line_, s);
        } else {
          if (!header_done_[static_cast<std::size_t>(t)]) {
            if constexpr (std::is_same_v<T, torque_EngineTorque>)
              line_ += kEngineHeader;
            else
              line_ += dds::table_header<T>();
            if (const char* legend = table_legend<T>()) line_ += legend;
            if constexpr (std::is_same_v<T, torque_EstimatorTorque>)
              line_ += std::string("# health: ") + kHealthCodes + "\n";
            if constexpr (std::is_same_v<T, torque_EngineTorque>)
              line_ += std::string("# q: ") + kHealthCodes + "\n";
            header_done_[static_cast<std::size_t>(t)] = true;
          }
          if constexpr (std::is_same_v<T, torque_EngineTorque>)
            append_engine_row(line_, s);
          else
            dds::append_table_row(line_, s);
          if (!plausible && !line_.empty() && line_.back() == '\n')
            line_.insert(line_.size() - 1, "  OUT OF RANGE");
        }
        std::fwrite(line_.data(), 1, line_.size(), stdout);
      }
    }
  }

  Options o_;
  dds::DdsSettings settings_;
  std::unique_ptr<dds::SampleRecorder> recorder_;
  dds_entity_t participant_ = 0, waitset_ = 0;
  Reader<torque_EngineTorque> engine_;
  Reader<torque_EstimatorTorque> estimator_;
  Reader<torque_CylinderTorque> cylinder_;
  Reader<torque_CrankState> crank_;
  Reader<torque_DaemonStatus> status_;
  std::array<bool, dds::kTopicCount> header_done_{};
  bool print_status_ = true;
  bool done_ = false;          ///< the daemon's status said REPLAY_DONE (a state: stays)
  bool exit_on_done_ = false;  ///< --until-done, or the status topic printed: exit when done
  bool lost_ = false;
  std::uint64_t received_ = 0;
  std::map<std::pair<int, std::uint16_t>, std::uint64_t> last_seq_;  ///< (topic*256 + method, engine) -> seq
  std::array<std::uint64_t, dds::kTopicCount> gaps_{};               ///< missing samples per topic
  std::array<std::uint64_t, dds::kTopicCount> out_of_range_{};       ///< implausible samples per topic
  dds::TorqueRange range_{};  ///< from --config's engine (none: finiteness only)
  std::string line_;
  std::string shm_topics_, net_topics_;  ///< " name name ...": readers on shared memory / on the network path
};

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "torque-echo: subscribe to torqued's DDS topics, print them (table or JSON lines) and/or record CSV "
      "for torque-eval. Set CYCLONEDDS_URI to a loopback-only configuration for local use."};
  app.add_option("--topic,-t", o.topics, "engine|estimator|cylinder|crank|status|all (repeatable)")
      ->check(CLI::IsMember({"engine", "estimator", "cylinder", "crank", "status", "all"}));
  app.add_option("--format,-f", o.format, "table|json|none")->check(CLI::IsMember({"table", "json", "none"}));
  app.add_option("--record,-r", o.record_dir, "write CSV files (engine_cycle.csv, ...) into this directory");
  app.add_flag("--cycles-only", o.cycles_only, "EngineTorque: only per-cycle samples (skip segments)");
  app.add_option("--config,-c", o.config,
                 "the daemon's configuration: DDS domain, topic prefix and each topic's QoS (reliability, "
                 "deadline, lease) from it, so the readers match its writers; --domain/--prefix override it")
      ->check(CLI::ExistingFile);
  auto* domain = app.add_option("--domain", o.domain, "DDS domain id (default 0, or the --config's)");
  auto* prefix = app.add_option("--prefix", o.prefix, "topic prefix (config dds.topic_prefix)");
  app.add_option("--history", o.history,
                 "reader keep-last depth per key (samples); more than the writer's, so a descheduled "
                 "subscriber loses nothing (iceoryx queues at most 256 of them)")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  app.add_flag("--no-deadline", o.no_deadline,
               "request no deadline (matches a writer offering none; needed for shared memory)");
  app.add_flag("--require-shm", o.require_shm,
               "exit with status 4 unless every reader receives through shared memory (iceoryx)");
  app.add_option("--duration", o.duration_s, "exit after this many seconds (0 = run until signalled)");
  app.add_option("--count", o.count, "exit after this many samples");
  app.add_flag("--until-done", o.until_done, "exit when the daemon's status reports the end of its replay");
  app.add_flag("--exit-on-lost", o.exit_on_lost,
               "exit with status 3 when the daemon's writers are gone: every subscribed topic that had a "
               "live writer has lost it (lost liveliness: it died or hangs; or it stopped)");
  app.add_option("--idle-exit", o.idle_exit_s,
                 "exit when no sample arrived for this many seconds (after the first)");
  app.add_flag("--quiet,-q", o.quiet, "no summary line on stderr");
  app.add_flag("--fail-on-gaps", o.fail_on_gaps,
               "exit 5 when samples were missing (sequence gaps per topic are reported at exit in any case)");
  app.add_flag(
      "--fail-on-range", o.fail_on_range,
      "exit 6 when a torque was outside the physical range of the --config's engine (such samples are "
      "counted at exit and their table rows marked OUT OF RANGE in any case)");
  app.footer(
      "Exit status: 0 done (signal, --count, --duration, --idle-exit or --until-done); 1 DDS error or "
      "invalid --config; 2 command-line error (unknown option, bad value); 3 the daemon's writers are gone "
      "(--exit-on-lost); 4 --require-shm and a reader is not on shared memory; 5 --fail-on-gaps and samples "
      "were missing (sequence gaps); 6 --fail-on-range and a torque was outside the engine's physical "
      "range.");
  TORQUED_CLI_PARSE(app, argc, argv);
  o.domain_given = domain->count() > 0;
  o.prefix_given = prefix->count() > 0;

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  try {
    Echo echo(o);
    return echo.run();
  } catch (const RequireShmError& e) {
    std::fprintf(stderr, "torque-echo: %s\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "torque-echo: %s\n", e.what());
    return 1;
  }
}
