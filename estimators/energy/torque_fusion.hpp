#pragma once
// Fused brake torque for the torque-split controller (docs/equations.md §4).
//
// Rule (documented in docs/angle_pipeline.md):
//  1. A source is usable when its health is kValid and, if it needs CAN, the CAN data is fresh (age <=
//  max_can_age_s).
//  2. The primary source is the first usable one in priority order:
//       kEnergyCan   Δ(½Jθ̇²)/4π + measured load (dyno / e-machine torque on CAN): exact energy balance, no
//       friction model kCrankOnly   Δ(½Jθ̇²)/4π + RLS extended load − learned friction: needs no CAN at all
//       kEso         ESO indicated torque (fuel on CAN) − learned friction
//       kExternal    any other estimate handed in (e.g. the time-domain UIO)
//  3. With `blend`, every other usable source whose difference from the primary is within gate_sigma·√(σp² +
//  σi²) is
//     blended with inverse-variance weights; otherwise the primary is used alone. The blend's 1σ is scaled by
//     the PDG factor √(χ²/(n−1)) when its sources disagree beyond their claimed 1σ (disagreement_scale).
//     Without blending and without the energy balance, the leader's 1σ takes the same factor from its
//     disagreement with the other usable sources within the gate (witness_scale).
//  4. Quality: kFull (primary uses CAN and crank), kCrankOnly (CAN lost or not needed: crank-only primary,
//  `can_lost`
//     says which), kDegraded (only model-based sources), kPriorOnly (the primary rests on priors only: the
//     fuel model with no reference and the generic friction law; its claimed 1σ is the priors' wide one),
//     kInvalid (nothing usable: the value holds the last good one and health says why; never NaN).
//  5. age_ns = t_ns − newest input time among the used sources.
#include <array>
#include <cstdint>

#include "estimate.hpp"
#include "params.hpp"

namespace torqued {

enum class FusionSourceId : std::uint8_t { kEnergyCan = 0, kCrankOnly = 1, kEso = 2, kExternal = 3 };
inline constexpr int kFusionSources = 4;

enum class FusionQuality : std::uint8_t {
  kFull = 0,
  kCrankOnly = 1,
  kDegraded = 2,
  kInvalid = 3,
  kPriorOnly = 4
};

[[nodiscard]] constexpr const char* to_string(FusionQuality q) noexcept {
  switch (q) {
    case FusionQuality::kFull:
      return "full";
    case FusionQuality::kCrankOnly:
      return "crank_only";
    case FusionQuality::kDegraded:
      return "degraded";
    case FusionQuality::kInvalid:
      return "invalid";
    case FusionQuality::kPriorOnly:
      return "prior_only";
  }
  return "unknown";
}

struct FusionSource {
  double brake_nm = 0.0;
  double sd_nm = 1.0;  ///< 1σ of the source (N m), > 0
  Health health = Health::kDisabled;
  bool uses_can = false;
  std::int64_t newest_input_ns = 0;  ///< newest input time that went into this value (ns)
  bool prior_only = false;           ///< rests on priors only (no reference learned): quality kPriorOnly
};

struct FusionInput {
  std::int64_t t_ns = 0;      ///< time of the decision (newest tooth) (ns)
  std::int64_t can_t_ns = 0;  ///< newest CAN frame time (ns)
  bool can_seen = false;      ///< any CAN frame at all
  std::array<FusionSource, kFusionSources> src{};
};

struct FusedTorque {
  std::int64_t t_ns = 0;
  double brake_nm = 0.0;
  double sd_nm = 0.0;
  FusionQuality quality = FusionQuality::kInvalid;
  FusionSourceId primary = FusionSourceId::kEnergyCan;
  std::uint8_t used_mask = 0;  ///< bit i: source i went into the value
  std::int64_t age_ns = 0;     ///< t_ns − newest input of the used sources (ns)
  bool can_lost = false;       ///< CAN older than max_can_age_s (or never seen)
  Health health = Health::kNotConverged;
};

class TorqueFusion {
 public:
  explicit TorqueFusion(const FusionParams& params) noexcept : params_(params) {}
  void reset() noexcept {
    out_ = FusedTorque{};
    have_good_ = false;
  }
  /// Real-time safe. Applies the rule above.
  const FusedTorque& update(const FusionInput& in) noexcept;
  [[nodiscard]] const FusedTorque& estimate() const noexcept { return out_; }

 private:
  /// Without blending and without the energy balance: the PDG factor (≥ 1) of the leader's disagreement with
  /// the other usable sources within the gate.
  [[nodiscard]] double witness_scale(const FusionInput& in, const std::array<bool, kFusionSources>& usable,
                                     int primary) const noexcept;
  /// PDG scale factor (≥ 1) of the blend of the sources in `used` around `mean`.
  [[nodiscard]] static double disagreement_scale(const FusionInput& in, std::uint8_t used,
                                                 double mean) noexcept;
  FusionParams params_;
  FusedTorque out_;
  bool have_good_ = false;
};

}  // namespace torqued
