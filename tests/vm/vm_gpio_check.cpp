// GPIO check, run inside the test VM (tests/vm/vm_gpio.sh loads gpio-sim.ko and creates the chip first):
// a 60-2 crank wheel is played on line 0 of a gpio-sim chip (a real kernel GPIO chip: gpiolib, the character
// device, line events from the chip's interrupt) by writing "pull-up"/"pull-down" to the line's sysfs `pull`
// attribute at the wheel's edge times; the daemon's backend (GpioEdgeSource, libgpiod v1) receives the
// kernel's line events and the crank decoder decodes them.
//   vm_gpio_check --chip LABEL|gpiochipN --pull /sys/devices/platform/gpio-sim.N/gpiochipM/sim_gpio0/pull
//                 [--revs 6] [--rpm-min 1500] [--rpm-max 6000] [--slow X (0 = measure)] [--budget-s 240]
// Speed profile: rpm-min for the first sixth of the revolutions, a linear ramp to rpm-max over the next half,
// rpm-max for the rest. One edge in flight at a time (see play()); the wheel runs in slow motion by the
// factor the VM's measured edge round trip and timer wake-up delay need (calibrate(); 1 where the machine
// keeps up, ~10-1000 under TCG; played again slower when the guest stalled the writer anyway), and the
// decoder's absolute-time settings are stretched by the same factor. So the assertions hold whatever the
// timing: every edge arrives (none lost or invented, levels as written), kernel timestamps increase and none
// precedes the write that caused it, tooth periods agree with the written ones, every tooth is counted, and
// the decoder does no worse than the same decoder on the writer's own clock: sync within two revolutions (or
// no later than there), no more losses, no more synced teeth with a wrong index (0 when the VM did not stall
// a write). Prints "PASS ..." / "FAIL ..." / "info: ..." lines; exit code 0 only if every assertion held.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "crank_decoder.hpp"
#include "gpio_source.hpp"
#include "vm_check.hpp"

namespace torqued {
namespace {

constexpr int kPositions = 60;  // 60-2: positions 0..57 carry teeth, 58 and 59 are the gap
constexpr int kTeeth = 58;
using vm::arg;
using vm::check;

std::int64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// One edge to write: time after the start (ns), level, and for rising edges the tooth number (0..57).
struct PlannedEdge {
  std::int64_t t_ns = 0;
  int level = 0;
  int tooth = -1;
};

/// The 60-2 wheel at the speed profile: rising edge at each tooth's start, falling edge half a pitch later.
std::vector<PlannedEdge> plan_wheel(int revs, double rpm_min, double rpm_max) {
  std::vector<PlannedEdge> plan;
  double t = 1e-3;  // s
  const double hold = revs / 6.0, ramp = revs / 2.0;
  for (int r = 0; r < revs; ++r) {
    for (int p = 0; p < kPositions; ++p) {
      const double x = r + static_cast<double>(p) / kPositions;
      const double f = std::clamp((x - hold) / ramp, 0.0, 1.0);
      const double pitch_s = 60.0 / ((rpm_min + f * (rpm_max - rpm_min)) * kPositions);
      if (p < kTeeth) {
        plan.push_back({static_cast<std::int64_t>(t * 1e9), 1, p});
        plan.push_back({static_cast<std::int64_t>((t + pitch_s / 2) * 1e9), 0, -1});
      }
      t += pitch_s;
    }
  }
  return plan;
}

/// Writes the plan to the line's pull attribute; written[k] = monotonic time just before write k. At most one
/// edge in flight: write k waits until the reader has received edge k-1 (`received`), because gpio-sim raises
/// its interrupt through irq_sim, which merges interrupts still pending, and the v1 uAPI reads the line's
/// level in the interrupt thread: a second level change before the first was handled would be lost or
/// mislabelled. When the wait makes a write late, the rest of the schedule slides by that much (later periods
/// keep their planned lengths; the late period is longer, as written).
struct Handshake {
  std::mutex m;
  std::condition_variable cv;
  std::size_t received = 0;
  void set(std::size_t n) {
    {
      const std::lock_guard<std::mutex> lock(m);
      received = n;
    }
    cv.notify_one();
  }
  void wait_for(std::size_t n) {  // blocks (no spinning: under emulation a spinning vCPU starves the other)
    std::unique_lock<std::mutex> lock(m);
    cv.wait_for(lock, std::chrono::seconds(5), [&] { return received >= n; });
  }
};

void play(int fd, const std::vector<PlannedEdge>& plan, std::vector<std::int64_t>& written, Handshake& hs,
          double slow, std::atomic<bool>& failed) {
  std::int64_t t0 = mono_ns() + 20'000'000;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    hs.wait_for(k);
    const auto planned = static_cast<std::int64_t>(static_cast<double>(plan[k].t_ns) * slow);
    const std::int64_t now = mono_ns();
    if (now > t0 + planned) t0 = now - planned;  // late: slide the schedule
    const std::int64_t due = t0 + planned;
    const timespec ts{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const char* v = plan[k].level ? "pull-up" : "pull-down";
    written[k] = mono_ns();
    if (pwrite(fd, v, std::strlen(v), 0) < 0) {
      std::printf("info: write %zu (%s) failed: %s\n", k, v, std::strerror(errno));
      failed = true;
      return;
    }
  }
}

struct Received {
  std::vector<EdgeEvent> edges;
  std::vector<ToothEvent> teeth;
  DecoderStats dec;
  SourceStats src;
};

Received receive(GpioEdgeSource& src, const std::atomic<bool>& done, std::size_t expected, Handshake& hs,
                 const DecoderParams& params) {
  Received r;
  r.edges.reserve(expected);
  r.teeth.reserve(expected);
  CrankDecoder dec(WheelGeometry{}, params);
  EdgeEvent e;
  ToothEvent t;
  std::int64_t quiet_since = mono_ns();
  for (;;) {
    const SourceStatus s = src.next(e);
    if (s == SourceStatus::kOk) {
      r.edges.push_back(e);
      hs.set(r.edges.size());
      if (dec.on_edge(e, t)) r.teeth.push_back(t);
      quiet_since = mono_ns();
      if (r.edges.size() == expected && done.load()) break;
    } else if (s == SourceStatus::kWouldBlock) {
      if (done.load() && mono_ns() - quiet_since > 2'000'000'000) break;
    } else {
      break;
    }
  }
  r.dec = dec.stats();
  r.src = src.stats();
  return r;
}

void check_edges(const std::vector<PlannedEdge>& plan, const std::vector<std::int64_t>& written,
                 const Received& r) {
  check(r.edges.size() == plan.size(), "gpio: " + std::to_string(r.edges.size()) + " line events for " +
                                           std::to_string(plan.size()) + " level changes written");
  check(r.src.dropped == 0,
        "gpio: no edge lost in the kernel FIFO (dropped " + std::to_string(r.src.dropped) + ")");
  const std::size_t n = std::min(r.edges.size(), plan.size());
  std::size_t wrong_level = 0, not_increasing = 0, before_write = 0;
  std::int64_t max_delay = 0;
  std::vector<std::int64_t> delay;
  delay.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (r.edges[k].level != plan[k].level) ++wrong_level;
    if (k > 0 && r.edges[k].t_ns <= r.edges[k - 1].t_ns) ++not_increasing;
    if (r.edges[k].t_ns < written[k]) ++before_write;
    max_delay = std::max(max_delay, r.edges[k].t_ns - written[k]);
    delay.push_back(r.edges[k].t_ns - written[k]);
  }
  std::sort(delay.begin(), delay.end());
  if (!delay.empty())
    std::printf("info: delay write -> kernel timestamp: median %.1f us, 90 %% %.1f us, 99 %% %.1f us\n",
                static_cast<double>(delay[delay.size() / 2]) * 1e-3,
                static_cast<double>(delay[delay.size() * 9 / 10]) * 1e-3,
                static_cast<double>(delay[delay.size() * 99 / 100]) * 1e-3);
  check(wrong_level == 0,
        "gpio: every event has the written level (" + std::to_string(wrong_level) + " wrong)");
  check(not_increasing == 0,
        "gpio: kernel timestamps strictly increasing (" + std::to_string(not_increasing) + " not)");
  check(before_write == 0,
        "gpio: no timestamp before its write (" + std::to_string(before_write) + " earlier)");
  std::printf("info: largest delay write -> kernel timestamp %.3f ms\n",
              static_cast<double>(max_delay) * 1e-6);
}

/// Rising-to-rising periods: kernel timestamps against the writer's clock, per tooth; the median ratio must
/// be near 1 and the sum over all teeth (the run's duration) must agree within 5 %.
void check_periods(const std::vector<PlannedEdge>& plan, const std::vector<std::int64_t>& written,
                   const Received& r, double slow) {
  const auto top_pitch_ns = static_cast<double>(plan[plan.size() - 2].t_ns - plan[plan.size() - 4].t_ns);
  std::vector<double> ratio;
  std::int64_t sum_kernel = 0, sum_written = 0, min_period = INT64_MAX;
  std::size_t prev = SIZE_MAX;
  const std::size_t n = std::min(r.edges.size(), plan.size());
  for (std::size_t k = 0; k < n; ++k) {
    if (plan[k].level != 1) continue;
    if (prev != SIZE_MAX) {
      const std::int64_t pk = r.edges[k].t_ns - r.edges[prev].t_ns, pw = written[k] - written[prev];
      ratio.push_back(static_cast<double>(pk) / static_cast<double>(std::max<std::int64_t>(pw, 1)));
      sum_kernel += pk;
      sum_written += pw;
      min_period = std::min(min_period, pk);
    }
    prev = k;
  }
  if (ratio.empty()) {
    check(false, "gpio: no tooth periods to compare");
    return;
  }
  std::nth_element(ratio.begin(), ratio.begin() + static_cast<std::ptrdiff_t>(ratio.size() / 2), ratio.end());
  const double med = ratio[ratio.size() / 2];
  const double total =
      static_cast<double>(sum_kernel) / static_cast<double>(std::max<std::int64_t>(sum_written, 1));
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "gpio: tooth periods plausible: median kernel/written %.3f (0.8 .. 1.25), total %.4f", med,
                total);
  check(med > 0.8 && med < 1.25 && std::fabs(total - 1.0) < 0.05, buf);
  std::printf(
      "info: run %.3f s planned, %.3f s written; shortest tooth period %.1f ms (top speed's %.3f ms "
      "x slow motion %.1f = %.1f ms)\n",
      static_cast<double>(plan.back().t_ns) * 1e-9,
      static_cast<double>(written.back() - written.front()) * 1e-9, static_cast<double>(min_period) * 1e-6,
      top_pitch_ns * 1e-6, slow, top_pitch_ns * slow * 1e-6);
}

/// How far the written wheel itself strays from the plan: written rising-to-rising periods against the
/// planned ones (times the slow motion). A VM that stalls a write makes one period long and, when the sleep
/// before the next write returns on time, the next one short; the decoder must then judge a wheel that was
/// written irregularly, on either clock. Returns the fraction of periods outside 0.8 .. 1.25 of the plan.
double report_written(const std::vector<PlannedEdge>& plan, const std::vector<std::int64_t>& written,
                      double slow) {
  std::size_t prev = SIZE_MAX, n = 0, off = 0;
  double lo = 1e9, hi = 0.0;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (plan[k].level != 1) continue;
    if (prev != SIZE_MAX) {
      const double want = static_cast<double>(plan[k].t_ns - plan[prev].t_ns) * slow;
      const double q = static_cast<double>(written[k] - written[prev]) / want;
      lo = std::min(lo, q);
      hi = std::max(hi, q);
      ++n;
      if (q < 0.8 || q > 1.25) ++off;
    }
    prev = k;
  }
  std::printf("info: written tooth periods / planned: %.3f .. %.3f; %zu of %zu outside 0.8 .. 1.25\n", lo, hi,
              off, n);
  return n > 0 ? static_cast<double>(off) / static_cast<double>(n) : 1.0;
}

/// The decoder on the writer's own clock (the times of the writes): what the kernel's timestamps should give.
Received decode_written(const std::vector<PlannedEdge>& plan, const std::vector<std::int64_t>& written,
                        const DecoderParams& params) {
  Received r;
  CrankDecoder dec(WheelGeometry{}, params);
  ToothEvent t;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    r.edges.push_back(EdgeEvent{written[k], 0, static_cast<std::uint8_t>(plan[k].level)});
    if (dec.on_edge(r.edges.back(), t)) r.teeth.push_back(t);
  }
  r.dec = dec.stats();
  return r;
}

/// Synced teeth of a decoded run against the written wheel: how many, how many with the wrong index, the
/// first synced rising edge and the top speed seen.
struct SyncedTeeth {
  std::size_t first = SIZE_MAX, wrong = 0, synced = 0;
  double max_rpm = 0.0;
};
SyncedTeeth synced_teeth(const std::vector<PlannedEdge>& plan, const Received& r) {
  SyncedTeeth st;
  std::size_t m = 0, k_tooth = 0;
  for (const PlannedEdge& p : plan) {
    if (p.level != 1) continue;
    if (m++ == 0) continue;
    if (k_tooth >= r.teeth.size() || 2 * (m - 1) >= r.edges.size()) break;
    const ToothEvent& t = r.teeth[k_tooth];
    if (t.source_t_ns != r.edges[2 * (m - 1)].t_ns) continue;  // rejected as a runt: no tooth event
    ++k_tooth;
    if (t.sync != SyncState::kSynced) continue;
    ++st.synced;
    if (st.first == SIZE_MAX) st.first = m - 1;
    if (t.tooth % kTeeth != p.tooth) ++st.wrong;
    st.max_rpm = std::max(st.max_rpm, t.speed_rad_s * 60.0 / (2.0 * M_PI));
  }
  return st;
}

/// Decoder: every tooth edge reached it, sync within two revolutions (or no later than on the writer's
/// clock), and no more sync losses and no more synced teeth with a wrong index than the same decoder has on
/// the writer's clock. A stalled VM can make a written period itself irregular (a runt the decoder rightly
/// rejects shifts the count until the gap): the kernel path must add nothing to what the written wheel itself
/// shows; on an undisturbed run both are 0.
void check_decoder(const std::vector<PlannedEdge>& plan, const Received& r, const Received& ref,
                   double slow) {
  const auto rising = static_cast<std::uint64_t>(
      std::count_if(plan.begin(), plan.end(), [](const PlannedEdge& p) { return p.level == 1; }));
  // The first rising edge only starts the first period: every later one is a tooth or a rejected runt.
  check(r.dec.teeth + r.dec.noise_edges == rising - 1,
        "gpio: decoder got " + std::to_string(r.dec.teeth) + " teeth + " + std::to_string(r.dec.noise_edges) +
            " runts of " + std::to_string(rising - 1) + " tooth edges (writer's clock: " +
            std::to_string(ref.dec.teeth) + " + " + std::to_string(ref.dec.noise_edges) + ")");
  check(r.dec.syncs >= 1 && r.dec.sync_losses <= ref.dec.sync_losses,
        "gpio: decoder synced (" + std::to_string(r.dec.syncs) + " syncs, " +
            std::to_string(r.dec.sync_losses) + " losses, last: " + to_string(r.dec.last_loss_reason) +
            "; on the writer's clock " + std::to_string(ref.dec.sync_losses) + " losses)");
  const SyncedTeeth k = synced_teeth(plan, r), w = synced_teeth(plan, ref);
  // Within two revolutions, or no later than on the writer's clock when a stalled write made the written
  // wheel itself lose the first sync (a run at 191x slow motion: both first synced at edge 116, 2 losses
  // each).
  check(k.synced > 0 && (k.first < 2 * kTeeth || k.first <= w.first),
        "gpio: synced at rising edge " + std::to_string(k.first) + " of the run (within two revolutions: < " +
            std::to_string(2 * kTeeth) +
            ", or no later than on the writer's clock: " + std::to_string(w.first) + ")");
  check(k.synced > 0 && k.wrong <= w.wrong,
        "gpio: no synced tooth with a wrong index beyond the written wheel's own (" +
            std::to_string(k.wrong) + " of " + std::to_string(k.synced) + " wrong; on the writer's clock " +
            std::to_string(w.wrong) + " of " + std::to_string(w.synced) + ")");
  std::printf(
      "info: decoder: %llu teeth, %zu synced, %llu lost teeth interpolated; top speed seen %.1f rpm (x "
      "slow motion = %.0f rpm of the wheel)\n",
      static_cast<unsigned long long>(r.dec.teeth), k.synced,
      static_cast<unsigned long long>(r.dec.lost_teeth), k.max_rpm, k.max_rpm * slow);
}

DecoderParams slow_params(double slow) {
  DecoderParams params;
  params.stall_timeout_ns = static_cast<std::int64_t>(static_cast<double>(params.stall_timeout_ns) * slow);
  params.lost_tooth_min_rpm /= slow;
  return params;
}

/// Plays `plan` (times stretched by `slow`) while receiving and decoding it.
/// The decoder's two absolute-time settings are stretched with it (the rest of its logic is ratios of
/// periods).
Received play_and_receive(GpioEdgeSource& src, int fd, const std::vector<PlannedEdge>& plan, double slow,
                          std::vector<std::int64_t>& written) {
  written.assign(plan.size(), 0);
  std::atomic<bool> done{false}, failed{false};
  Handshake hs;
  const DecoderParams params = slow_params(slow);
  std::thread writer([&] {
    play(fd, plan, written, hs, slow, failed);
    done = true;
  });
  Received r = receive(src, done, plan.size(), hs, params);
  writer.join();
  check(!failed, "gpio: every level change written");
  return r;
}

/// Slow motion: the VM's round trip per edge (write -> interrupt -> line event -> reader) is measured on 64
/// edges written back to back; the wheel is played that many times slower that its shortest edge spacing
/// is 3x the 90th percentile of the round trip (1 = real time, e.g. under KVM or on hardware).
/// The guest's timer: how late an absolute sleep of ~1 ms wakes (48 sleeps, sorted). Under emulation a
/// wake-up can be milliseconds late; a late write lengthens one written period and shortens the next.
std::vector<std::int64_t> sleep_overshoots() {
  std::vector<std::int64_t> late;
  for (int k = 0; k < 48; ++k) {
    const std::int64_t due = mono_ns() + 1'000'000;
    const timespec ts{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    late.push_back(std::max<std::int64_t>(0, mono_ns() - due));
  }
  std::sort(late.begin(), late.end());
  return late;
}

double calibrate(GpioEdgeSource& src, int fd, double min_spacing_ns, double min_tooth_ns, double planned_s,
                 double budget_s) {
  std::vector<PlannedEdge> burst(64);
  for (std::size_t k = 0; k < burst.size(); ++k) burst[k].level = k % 2 == 0 ? 1 : 0;
  std::vector<std::int64_t> written;
  const Received r = play_and_receive(src, fd, burst, 1.0, written);
  std::vector<std::int64_t> rtt;
  for (std::size_t k = 1; k < written.size(); ++k) rtt.push_back(written[k] - written[k - 1]);
  std::sort(rtt.begin(), rtt.end());
  const double p90 = static_cast<double>(rtt[rtt.size() * 9 / 10]);
  check(r.edges.size() == burst.size(), "gpio: calibration burst: " + std::to_string(r.edges.size()) +
                                            " events for " + std::to_string(burst.size()) + " writes");
  // The wheel must also be written regularly enough for the decoder to judge it: the 90th percentile of the
  // wake-up delay within 5 % of the shortest tooth period, the largest within 25 %.
  const std::vector<std::int64_t> late = sleep_overshoots();
  const auto late90 = static_cast<double>(late[late.size() * 9 / 10]);
  const auto late_max = static_cast<double>(late.back());
  double slow = std::max(
      {1.0, 3.0 * p90 / min_spacing_ns, late90 / (0.05 * min_tooth_ns), late_max / (0.25 * min_tooth_ns)});
  std::printf("info: sleep wake-up delay: median %.1f us, 90 %% %.1f us, largest %.1f us\n",
              static_cast<double>(late[late.size() / 2]) * 1e-3, late90 * 1e-3, late_max * 1e-3);
  if (slow * planned_s > budget_s) {
    std::printf("info: slow motion %.0fx would take %.0f s: capped at %.0f s (writes may run late)\n", slow,
                slow * planned_s, budget_s);
    slow = std::max(1.0, budget_s / planned_s);
  }
  std::printf(
      "info: round trip per edge: median %.1f us, 90 %% %.1f us -> wheel played %.1fx slower than real\n",
      static_cast<double>(rtt[rtt.size() / 2]) * 1e-3, p90 * 1e-3, slow);
  return slow;
}

int run(int argc, char** argv) {
  const std::string pull = arg(argc, argv, "--pull", "");
  const int revs = std::stoi(arg(argc, argv, "--revs", "6"));
  const double rpm_min = std::stod(arg(argc, argv, "--rpm-min", "1500"));
  const double budget_s = std::stod(arg(argc, argv, "--budget-s", "240"));
  const double rpm_max = std::stod(arg(argc, argv, "--rpm-max", "6000"));
  const double slow_arg = std::stod(arg(argc, argv, "--slow", "0"));  // 0 = calibrate
  GpioConfig cfg;
  cfg.chip = arg(argc, argv, "--chip", "torqued-crank");
  cfg.crank_line = 0;
  cfg.to_realtime = false;  // compare with the writer's CLOCK_MONOTONIC (the default adds a fixed offset)
  GpioEdgeSource src(cfg);
  check(src.ok(), "gpio: GpioEdgeSource on " + src.describe() + " " + src.last_error());
  const int fd = ::open(pull.c_str(), O_WRONLY | O_CLOEXEC);
  check(fd >= 0, "gpio: opened " + pull + (fd < 0 ? std::string(": ") + std::strerror(errno) : ""));
  if (!src.ok() || fd < 0) return 1;

  const std::vector<PlannedEdge> plan = plan_wheel(revs, rpm_min, rpm_max);
  double min_spacing = 1e18;
  for (std::size_t k = 1; k < plan.size(); ++k)
    min_spacing = std::min(min_spacing, static_cast<double>(plan[k].t_ns - plan[k - 1].t_ns));
  double min_tooth = 1e18;
  for (std::size_t k = 2; k < plan.size(); ++k)
    if (plan[k].level == 1)
      min_tooth = std::min(min_tooth, static_cast<double>(plan[k].t_ns - plan[k - 2].t_ns));
  const double planned_s = static_cast<double>(plan.back().t_ns) * 1e-9;
  double slow = slow_arg > 0 ? slow_arg : calibrate(src, fd, min_spacing, min_tooth, planned_s, budget_s);
  // A guest that stalls while the wheel is written (a busy host) writes an irregular wheel, which no decoder
  // could judge: then the wheel is played again at twice the slow motion (at most three plays, within the
  // budget: the plays' total, so the run ends with a verdict before run_in_vm.sh's timeout), and the checks
  // below judge the last play.
  std::vector<std::int64_t> written;
  Received r;
  double played_s = 0;
  for (int play = 1;; ++play) {
    r = play_and_receive(src, fd, plan, slow, written);
    played_s += slow * planned_s;
    const double off = report_written(plan, written, slow);
    if (off <= 0.05 || play == 3 || played_s + 2.0 * slow * planned_s > budget_s) break;
    slow *= 2.0;
    std::printf("info: %.0f %% of the written periods strayed from the plan: played again at %.1fx\n",
                off * 100.0, slow);
  }
  ::close(fd);
  check_edges(plan, written, r);
  check_periods(plan, written, r, slow);
  check_decoder(plan, r, decode_written(plan, written, slow_params(slow)), slow);
  return vm::failures() == 0 ? 0 : 1;
}

}  // namespace
}  // namespace torqued

int main(int argc, char** argv) { return torqued::run(argc, argv); }
