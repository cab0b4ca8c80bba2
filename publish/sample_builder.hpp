#pragma once
// The one builder of EstimatorTorque samples, shared by the angle and the time stage: an estimate, its method
// id (idl/methods.hpp) and its per-method sequence number become one topic sample with the shared validity
// mapping (validity.hpp). Real-time safe.
#include <cstdint>

#include "estimate.hpp"
#include "sample.hpp"
#include "validity.hpp"

namespace torqued {

/// False (nothing to publish) for a switched-off estimator; otherwise fills `a`.
[[nodiscard]] inline bool estimator_sample(std::uint8_t method, std::uint64_t seq, const TorqueEstimate& e,
                                           std::int64_t t_ns, std::int64_t ingest_ns,
                                           dds::AnySample& a) noexcept {
  if (e.health == Health::kDisabled) return false;
  a.topic = dds::Topic::kEstimatorTorque;
  auto& m = a.u.estimator;
  m.method = method;
  m.seq = seq;
  m.source_t_ns = t_ns;
  m.ingest_t_ns = ingest_ns;
  m.value_nm = e.torque_nm;
  m.uncertainty = e.uncertainty;
  m.health = static_cast<std::uint8_t>(e.health);
  m.validity = validity_of(e);
  return true;
}

}  // namespace torqued
