// tests/service/test_runtime_alloc.cpp: the real-time threads of the paced runtime (source, angle, time) make
// no heap allocation after their set-up, over a full replay. This binary has its own counting operator new
// (per thread, thread_local) — enabled only here — and reads it through Runtime's rt_thread_hook at the
// start and the end of each real-time thread.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <new>
#include <string>

#include "edge_file_source.hpp"
#include "runtime.hpp"
#include "synthetic_edge_csv.hpp"

namespace {
thread_local std::size_t t_allocs = 0;
void* counted(std::size_t n) {
  ++t_allocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
}  // namespace
void* operator new(std::size_t n) { return counted(n); }
void* operator new[](std::size_t n) { return counted(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace torqued {
namespace {

class NullSink final : public SampleSink {
 public:
  void emit(const dds::AnySample&) noexcept override { n.fetch_add(1, std::memory_order_relaxed); }
  std::atomic<std::uint64_t> n{0};
};

TEST(RuntimeAllocation, RealTimeThreadsDoNotAllocateOverAFullReplay) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("torqued_rt_alloc_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "edges.csv").string();
  // 1.5 s of a 60-2 wheel ramping 2000 -> 4000 rpm, replayed at 5x: all pipelines run, with cycle ends.
  ASSERT_GT(test::write_edge_csv(path, test::WheelRun{2000.0, 4000.0, 1.5}), 1000);

  StageSettings s;
  RuntimeOptions o;
  o.speed = 5.0;
  o.lock_memory = false;
  o.publisher_spin_ns = 150'000;  // the daemon's default: the publisher pre-wake path runs (and under TSan)
  std::mutex m;
  // thread -> (at start, at exit); entries exist before the threads start so the hook itself never allocates.
  std::map<std::string, std::pair<std::size_t, std::size_t>> counts{
      {"torqued-source", {}}, {"torqued-angle", {}}, {"torqued-time", {}}};
  std::map<std::string, int> calls{{"torqued-source", 0}, {"torqued-angle", 0}, {"torqued-time", 0}};
  o.rt_thread_hook = [&](const char* name, bool exiting) {
    const std::size_t c = t_allocs;  // read before anything here allocates
    std::lock_guard<std::mutex> lk(m);
    auto& e = counts.find(name)->second;
    ++calls.find(name)->second;
    (exiting ? e.second : e.first) = c;
  };
  EdgeCsvSource src(path, {});
  ASSERT_TRUE(src.ok());
  NullSink sink;
  Runtime rt(s, o, &src, nullptr, 0, nullptr, sink);
  ASSERT_TRUE(rt.ok()) << rt.error();
  ASSERT_TRUE(rt.start()) << rt.error();
  for (int i = 0; i < 200 && !rt.input_done(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(rt.input_done());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_TRUE(rt.stop_and_drain(1'000'000'000));
  const RuntimeCounters c = rt.counters();
  EXPECT_GT(c.cycles, 20u);
  EXPECT_GT(sink.n.load(), 100u);
  EXPECT_EQ(c.ring_drops_edge + c.ring_drops_out, 0u);
  EXPECT_GT(c.publisher_polls, 100u) << "the publisher pre-wakes for the tooth edges of a paced replay";
  ASSERT_EQ(counts.size(), 3u) << "source, angle and time threads";
  for (const auto& [name, n] : calls) EXPECT_EQ(n, 2) << name << ": hook not called at start and exit";
  for (const auto& [name, ab] : counts)
    EXPECT_EQ(ab.second, ab.first) << name << " allocated " << (ab.second - ab.first) << " times after start";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace torqued
