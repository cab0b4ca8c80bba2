#include "sink_thread.hpp"

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
  if (ring_.full()) {
    ++waits_;
    unsigned round = 0;
    while (ring_.full()) back_off(round);
  }
  (void)ring_.try_push(s);  // room was made above and only this thread pushes: counted in drops() if refused
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
