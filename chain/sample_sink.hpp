#pragma once
// Where the stages put their outputs. Fast replay: straight into the recorder/publisher (one thread).
// Paced/live: into SPSC rings towards the publisher and the time stage (RingSink in runtime.cpp).
// Implementations must be real-time safe (no allocation, no lock, no blocking).
#include "sample.hpp"
#include "samples.hpp"

namespace torqued {

class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void emit(const dds::AnySample& s) noexcept = 0;
  /// End of a run: buffered output goes to its files (not called on the real-time threads).
  virtual void flush() noexcept {}
};

/// Tooth samples from the angle stage to the time stage (mean speed for the time-domain estimators).
class ToothSink {
 public:
  virtual ~ToothSink() = default;
  virtual void tooth(const ToothSample& t) noexcept = 0;
};

}  // namespace torqued
