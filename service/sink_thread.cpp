#include "sink_thread.hpp"

#include <cstring>

#include "back_off.hpp"

namespace torqued {

SinkThread::SinkThread(SampleSink& inner, std::size_t capacity)
    : inner_(inner), ring_(capacity), thread_([this] { run(); }) {}

SinkThread::~SinkThread() { flush(); }

void SinkThread::emit(const dds::AnySample& s) noexcept {
  if (joined_) {
    inner_.emit(s);
    return;
  }
  dds::AnySample* slot = ring_.claim();
  if (slot == nullptr) {
    ++waits_;
    unsigned round = 0;
    while ((slot = ring_.claim()) == nullptr) back_off(round);
  }
  // Only the topic's own struct: the recorder reads nothing else, and the rest of the 272 bytes would be
  // cache lines to carry to the writer's core for nothing (an EstimatorTorque, 9 in 10 samples, is 72 bytes).
  slot->topic = s.topic;
  s.visit([&](const auto& v) {
    std::memcpy(static_cast<void*>(reinterpret_cast<unsigned char*>(&slot->u)), &v, sizeof(v));
  });
  ring_.publish();
}

void SinkThread::flush() noexcept {
  if (joined_) return;
  done_.store(true, std::memory_order_release);
  thread_.join();
  joined_ = true;
  inner_.flush();
}

void SinkThread::run() noexcept {
  std::uint64_t n = 0;
  for (;;) {
    if (const dds::AnySample* s = ring_.front()) {
      inner_.emit(*s);
      ring_.pop_front();
      written_.store(++n, std::memory_order_release);
      continue;
    }
    // Empty: done_ is read before the last look at the ring, so a sample pushed before done_ was set is seen.
    if (done_.load(std::memory_order_acquire)) {
      if (ring_.front() == nullptr) return;
      continue;
    }
    rest();
  }
}

}  // namespace torqued
