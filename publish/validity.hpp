#pragma once
// The one mapping from an estimator's Health (and value) to the validity bits of the published topics, used
// by every stage, so a Health value is flagged the same way on every topic.
#include <cmath>
#include <cstdint>

#include "estimate.hpp"
#include "sample.hpp"

namespace torqued {

[[nodiscard]] constexpr std::uint32_t validity_of(Health h) noexcept {
  switch (h) {
    case Health::kValid:
      return 0;
    case Health::kNotConverged:
    case Health::kNotExcited:
      return torque_VALIDITY_NOT_CONVERGED;
    case Health::kStaleInput:
      return torque_VALIDITY_STALE_CAN;
    case Health::kNoSync:
      return torque_VALIDITY_NO_SYNC;
    case Health::kInvalidInput:
    case Health::kNumerical:
    case Health::kDisabled:  // a value from a switched-off estimator is never valid
      break;
  }
  return torque_VALIDITY_ESTIMATOR_FAULT;
}

/// Health bits, plus ESTIMATOR_FAULT for a non-finite value: NaN never leaves silently.
[[nodiscard]] inline std::uint32_t validity_of(Health h, double value) noexcept {
  return validity_of(h) |
         (std::isfinite(value) ? 0u : static_cast<std::uint32_t>(torque_VALIDITY_ESTIMATOR_FAULT));
}

[[nodiscard]] inline std::uint32_t validity_of(const TorqueEstimate& e) noexcept {
  return validity_of(e.health, e.torque_nm);
}

}  // namespace torqued
