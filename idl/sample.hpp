#pragma once
// One output record of any torque topic: what the pipelines push into the output rings and what the publisher
// and recorder consume. Trivially copyable (C structs from idlc), fixed size.
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>

#include "topics.hpp"

namespace torqued::dds {

struct AnySample {
  Topic topic = Topic::kEngineTorque;
  union U {
    torque_EngineTorque engine;
    torque_EstimatorTorque estimator;
    torque_CylinderTorque cylinder;
    torque_CrankState crank;
    torque_DaemonStatus status;
  } u;
  /// Zero-filled, so the bytes of unset fields are deterministic. `u{}` (value-initialising the 264-byte
  /// union) compiled to `rep stosq`, slow to start for every sample on this CPU; word stores become vector
  /// stores (perf3: AngleStage::on_tooth's share of the fast replay ≈ −20 %).
  AnySample() noexcept {
    using Word = std::uint64_t __attribute__((may_alias));
    auto* w = reinterpret_cast<Word*>(&u);
    // Fully unrolled up to 64 words: a partly unrolled loop (the union grew past 32 words with DaemonStatus'
    // fuel fields) was turned back into `rep stosq` (AngleStage::emit_method: 34 of its 79 instructions).
    static_assert(sizeof(U) / sizeof(Word) <= 64, "raise the unroll count below");
#pragma GCC unroll 64
    for (std::size_t i = 0; i < sizeof(U) / sizeof(Word); ++i) w[i] = 0;
  }

  /// The header fields every topic shares, by reference (no allocation; real-time safe).
  template <class F>
  decltype(auto) visit(F&& f) {
    return visit_impl(*this, std::forward<F>(f));
  }
  template <class F>
  decltype(auto) visit(F&& f) const {
    return visit_impl(*this, std::forward<F>(f));
  }

 private:
  template <class Self, class F>
  static decltype(auto) visit_impl(Self& self, F&& f) {
    switch (self.topic) {
      case Topic::kEngineTorque:
        return f(self.u.engine);
      case Topic::kEstimatorTorque:
        return f(self.u.estimator);
      case Topic::kCylinderTorque:
        return f(self.u.cylinder);
      case Topic::kCrankState:
        return f(self.u.crank);
      case Topic::kDaemonStatus:
        break;
    }
    return f(self.u.status);
  }
};
static_assert(std::is_trivially_copyable_v<AnySample>);
static_assert(sizeof(AnySample::U) % sizeof(std::uint64_t) == 0 &&
              alignof(AnySample::U) >= alignof(std::uint64_t));

}  // namespace torqued::dds
