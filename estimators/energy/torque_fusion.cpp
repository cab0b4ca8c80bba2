#include "torque_fusion.hpp"

#include <cmath>

namespace torqued {

double TorqueFusion::disagreement_scale(const FusionInput& in, std::uint8_t used, double mean) noexcept {
  // The Particle Data Group's scale factor for inconsistent measurements (Review of Particle Physics,
  // "Introduction: averaging"): S = √(χ² / (n − 1)), χ² = Σ (x_i − x̄)² / σ_i², applied when S > 1. Blended
  // sources farther apart than their claimed 1σ say so: at least one of those claims is too small there (a
  // chain whose 1σ was measured at other operating points).
  double chi2 = 0.0;
  int n = 0;
  for (int i = 0; i < kFusionSources; ++i) {
    if (!((used >> i) & 1u)) continue;
    const FusionSource& s = in.src[static_cast<std::size_t>(i)];
    const double d = (s.brake_nm - mean) / s.sd_nm;
    chi2 += d * d;
    ++n;
  }
  return n > 1 && chi2 > n - 1 ? std::sqrt(chi2 / (n - 1)) : 1.0;
}

double TorqueFusion::witness_scale(const FusionInput& in, const std::array<bool, kFusionSources>& usable,
                                   int primary) const noexcept {
  // Without the energy balance the leader is the source claiming the smallest 1σ, and each claim was measured
  // at the references' operating points only. The other usable sources within the gate are witnesses: when
  // they sit farther from the leader than the claims allow (χ² of the differences over n − 1 above 1), the
  // leader's 1σ takes the same PDG scale factor.
  const FusionSource& p = in.src[static_cast<std::size_t>(primary)];
  double chi2 = 0.0;
  int n = 0;
  for (int i = 0; i < kFusionSources; ++i) {
    const FusionSource& s = in.src[static_cast<std::size_t>(i)];
    if (i == primary || !usable[static_cast<std::size_t>(i)]) continue;
    const double v = p.sd_nm * p.sd_nm + s.sd_nm * s.sd_nm;
    const double d2 = (s.brake_nm - p.brake_nm) * (s.brake_nm - p.brake_nm);
    if (d2 > params_.gate_sigma * params_.gate_sigma * v) continue;  // outside the gate: not a witness
    chi2 += d2 / v;
    ++n;
  }
  return n > 0 && chi2 > n ? std::sqrt(chi2 / n) : 1.0;
}

const FusedTorque& TorqueFusion::update(const FusionInput& in) noexcept {
  FusedTorque o;
  o.t_ns = in.t_ns;
  const double can_age_s = static_cast<double>(in.t_ns - in.can_t_ns) * 1e-9;
  o.can_lost = !in.can_seen || can_age_s > params_.max_can_age_s;

  std::array<bool, kFusionSources> usable{};
  int primary = -1;
  for (int i = 0; i < kFusionSources; ++i) {
    const FusionSource& s = in.src[static_cast<std::size_t>(i)];
    usable[static_cast<std::size_t>(i)] = s.health == Health::kValid && std::isfinite(s.brake_nm) &&
                                          s.sd_nm > 0.0 && std::isfinite(s.sd_nm) &&
                                          !(s.uses_can && o.can_lost);
    if (primary < 0 && usable[static_cast<std::size_t>(i)]) primary = i;
  }
  // Rule 2b: without the energy balance (no measured load), the usable source with the smallest claimed 1σ
  // leads (the claimed σ of the crank-only and model-based sources are measured against the balance while it
  // was there).
  if (primary > 0) {
    for (int i = primary + 1; i < kFusionSources; ++i) {
      const auto iu = static_cast<std::size_t>(i);
      if (usable[iu] && in.src[iu].sd_nm < in.src[static_cast<std::size_t>(primary)].sd_nm) primary = i;
    }
  }
  if (primary < 0) {
    // Nothing usable: hold the last good value, say so.
    o.brake_nm = have_good_ ? out_.brake_nm : 0.0;
    o.sd_nm = have_good_ ? out_.sd_nm : 0.0;
    o.quality = FusionQuality::kInvalid;
    o.primary = out_.primary;
    o.health = o.can_lost ? Health::kStaleInput : Health::kNotConverged;
    o.age_ns = have_good_ ? in.t_ns - (out_.t_ns - out_.age_ns) : 0;
    out_ = o;
    return out_;
  }
  const FusionSource& p = in.src[static_cast<std::size_t>(primary)];
  double wsum = 1.0 / (p.sd_nm * p.sd_nm);
  double xsum = p.brake_nm * wsum;
  std::int64_t newest = p.newest_input_ns;
  o.used_mask = static_cast<std::uint8_t>(1u << primary);
  if (params_.blend) {
    for (int i = 0; i < kFusionSources; ++i) {
      if (i == primary || !usable[static_cast<std::size_t>(i)]) continue;
      const FusionSource& s = in.src[static_cast<std::size_t>(i)];
      const double gate = params_.gate_sigma * std::sqrt(p.sd_nm * p.sd_nm + s.sd_nm * s.sd_nm);
      if (std::fabs(s.brake_nm - p.brake_nm) > gate) continue;
      const double w = 1.0 / (s.sd_nm * s.sd_nm);
      wsum += w;
      xsum += w * s.brake_nm;
      if (s.newest_input_ns > newest) newest = s.newest_input_ns;
      o.used_mask = static_cast<std::uint8_t>(o.used_mask | (1u << i));
    }
  }
  o.brake_nm = xsum / wsum;
  o.sd_nm = std::sqrt(1.0 / wsum) * disagreement_scale(in, o.used_mask, o.brake_nm);
  if (primary > 0 && !params_.blend) o.sd_nm *= witness_scale(in, usable, primary);
  o.primary = static_cast<FusionSourceId>(primary);
  switch (o.primary) {
    case FusionSourceId::kEnergyCan:
      o.quality = FusionQuality::kFull;
      break;
    case FusionSourceId::kCrankOnly:
      o.quality = FusionQuality::kCrankOnly;
      break;
    default:
      o.quality = p.prior_only ? FusionQuality::kPriorOnly : FusionQuality::kDegraded;
      break;
  }
  o.age_ns = in.t_ns - newest;
  o.health = Health::kValid;
  have_good_ = true;
  out_ = o;
  return out_;
}

}  // namespace torqued
