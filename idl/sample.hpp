#pragma once
// One output record of any torque topic: what the pipelines push into the output rings and what the publisher
// and recorder consume. Trivially copyable (C structs from idlc), fixed size.
#include <cstdint>
#include <type_traits>

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
  } u{};

  /// The header fields every topic shares, by reference (no allocation; real-time safe).
  template <class F> decltype(auto) visit(F&& f) {
    switch (topic) {
      case Topic::kEngineTorque: return f(u.engine);
      case Topic::kEstimatorTorque: return f(u.estimator);
      case Topic::kCylinderTorque: return f(u.cylinder);
      case Topic::kCrankState: return f(u.crank);
      case Topic::kDaemonStatus: break;
    }
    return f(u.status);
  }
  template <class F> decltype(auto) visit(F&& f) const {
    switch (topic) {
      case Topic::kEngineTorque: return f(u.engine);
      case Topic::kEstimatorTorque: return f(u.estimator);
      case Topic::kCylinderTorque: return f(u.cylinder);
      case Topic::kCrankState: return f(u.crank);
      case Topic::kDaemonStatus: break;
    }
    return f(u.status);
  }
};
static_assert(std::is_trivially_copyable_v<AnySample>);

}  // namespace torqued::dds
