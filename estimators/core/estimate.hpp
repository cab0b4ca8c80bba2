#pragma once
// The small surface every estimator shares (docs/conventions.md habit 2): reset(), update(const Sample&)
// noexcept, estimate() const with a health field. Each estimator defines its own Sample type; this header
// holds the shared output record and health codes.
#include <cstdint>

namespace torqued {

/// Why an estimate may not be used. Ordered: anything but kValid means "do not use for control".
enum class Health : std::uint8_t {
  kValid = 0,
  kNotConverged = 1,  ///< running, but still inside its convergence time / cycles
  kNotExcited = 2,    ///< adaptive estimator: λ_min(P) below σ (Na Remark 9)
  kStaleInput = 3,    ///< an input signal is older than its time-out
  kInvalidInput = 4,  ///< NaN / out-of-range input rejected
  kNoSync = 5,        ///< crank decoder not synced (angle-based estimators)
  kNumerical = 6,     ///< factorisation failed / non-finite state; estimator reset itself
  kDisabled = 7,
};

[[nodiscard]] constexpr const char* to_string(Health h) noexcept {
  switch (h) {
    case Health::kValid:
      return "valid";
    case Health::kNotConverged:
      return "not_converged";
    case Health::kNotExcited:
      return "not_excited";
    case Health::kStaleInput:
      return "stale_input";
    case Health::kInvalidInput:
      return "invalid_input";
    case Health::kNoSync:
      return "no_sync";
    case Health::kNumerical:
      return "numerical";
    case Health::kDisabled:
      return "disabled";
  }
  return "unknown";
}

/// One torque estimate as every estimator reports it.
struct TorqueEstimate {
  std::int64_t t_ns = 0;     ///< source timestamp: the tooth edge or CAN frame the estimate came from (ns)
  double torque_nm = 0.0;    ///< the estimated quantity (N m); which torque depends on the estimator
  double uncertainty = 0.0;  ///< 1-sigma (N m) where known, or the excitation level λ_min(P) (adaptive)
  Health health = Health::kNotConverged;
};

/// Copies an estimate field by field. The per-tooth observers write their estimate field by field just before
/// the pipeline copies it; a struct copy reads it with 16-byte loads that span two of those 8-byte stores and
/// stalls on store forwarding (the two per-tooth copies were ≈ 1.5 % of the fast replay loop). The empty asm
/// statement only keeps GCC from merging the two doubles into such a load again; the values are unchanged.
inline void copy_estimate(TorqueEstimate& to, const TorqueEstimate& from) noexcept {
  to.t_ns = from.t_ns;
  to.torque_nm = from.torque_nm;
  asm("" ::: "memory");
  to.uncertainty = from.uncertainty;
  to.health = from.health;
}

}  // namespace torqued
