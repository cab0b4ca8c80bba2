// bench_ring: our SpscRing vs moodycamel::ReaderWriterQueue vs boost::lockfree::spsc_queue, for the
// 16-byte EdgeEvent record: (a) push+pop in one thread (pure cost), (b) producer/consumer on two threads
// (throughput). Not in ctest; run build-*/tests/rt/bench_ring.
#include <benchmark/benchmark.h>
#include <readerwriterqueue/readerwriterqueue.h>

#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <thread>

#include "records.hpp"
#include "spsc_ring.hpp"

namespace {
using torqued::EdgeEvent;
constexpr std::size_t kCap = 4096;

struct Ours {
  torqued::SpscRing<EdgeEvent> q{kCap};
  bool push(const EdgeEvent& e) { return q.try_push(e); }
  bool pop(EdgeEvent& e) { return q.try_pop(e); }
};
struct Moody {
  moodycamel::ReaderWriterQueue<EdgeEvent> q{kCap};
  bool push(const EdgeEvent& e) { return q.try_enqueue(e); }  // try_enqueue never allocates
  bool pop(EdgeEvent& e) { return q.try_dequeue(e); }
};
struct Boost {
  boost::lockfree::spsc_queue<EdgeEvent, boost::lockfree::capacity<kCap>> q;
  bool push(const EdgeEvent& e) { return q.push(e); }
  bool pop(EdgeEvent& e) { return q.pop(e); }
};

template <class Q>
void BM_PushPopSameThread(benchmark::State& st) {
  auto q = std::make_unique<Q>();
  EdgeEvent e{}, out{};
  for (auto _ : st) {
    e.t_ns++;
    benchmark::DoNotOptimize(q->push(e));
    benchmark::DoNotOptimize(q->pop(out));
  }
  st.SetItemsProcessed(st.iterations());
}

template <class Q>
void BM_TwoThreads(benchmark::State& st) {
  constexpr std::int64_t kBatch = 1 << 20;
  for (auto _ : st) {
    auto q = std::make_unique<Q>();
    std::atomic<bool> go{false};
    std::thread consumer([&] {
      EdgeEvent out{};
      std::int64_t n = 0;
      while (!go.load(std::memory_order_acquire)) {
      }
      while (n < kBatch)
        if (q->pop(out)) ++n;
    });
    go.store(true, std::memory_order_release);
    EdgeEvent e{};
    for (std::int64_t i = 0; i < kBatch;) {
      e.t_ns = i;
      if (q->push(e)) ++i;
    }
    consumer.join();
  }
  st.SetItemsProcessed(st.iterations() * kBatch);
}

BENCHMARK(BM_PushPopSameThread<Ours>)->Name("push_pop/same_thread/ours");
BENCHMARK(BM_PushPopSameThread<Moody>)->Name("push_pop/same_thread/moodycamel");
BENCHMARK(BM_PushPopSameThread<Boost>)->Name("push_pop/same_thread/boost");
BENCHMARK(BM_TwoThreads<Ours>)
    ->Name("transfer/two_threads/ours")
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_TwoThreads<Moody>)
    ->Name("transfer/two_threads/moodycamel")
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_TwoThreads<Boost>)
    ->Name("transfer/two_threads/boost")
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);
}  // namespace

BENCHMARK_MAIN();
