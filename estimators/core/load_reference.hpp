#pragma once
// Load references on a vehicle (docs/angle_pipeline.md "Load references"): which source fixes the load on the
// crank at one instant, and how well. On a vehicle there is no dynamometer; the balances J θ̈ = T_ind − T_fric
// − T_net still have a known T_net whenever the driveline is disconnected:
//   kLoadSignal    a measured load (torque flange / dynamometer, can.signals.load_torque), the machine folded
//   in kEMachineSole  the electric machine is the only load: clutch to the wheels open
//   (can.signals.em_sole_load,
//                  or the static can.e_machine.sole_load on a bench): T_net = T_acc − T_em,crank
//   kNeutral       clutch open / neutral without a machine (can.signals.neutral): T_net = T_acc (−
//   T_em,crank)
//   kFreeCoast     no flag mapped: a fuel cut-off the crank shows to be a free coast-down (clutch open;
//                  AnglePipeline::detect_free_coast): T_net = T_acc
//   kNone          nothing fixes the load (clutch closed, no load signal): nothing may be learned
// T_acc is the accessories' torque (alternator, pumps): unknown on a vehicle, a prior with its own 1σ
// (can.load_reference.*). A bench (the static sole_load, no flag signal mapped) has no accessories. Each kind
// carries its 1σ to the balances and learners (AnglePipeline::cycle_reference). Header only, real-time safe.
#include <cmath>
#include <cstdint>

#include "e_machine.hpp"
#include "samples.hpp"

namespace torqued {

enum class ReferenceKind : std::uint8_t { kNone = 0, kLoadSignal, kEMachineSole, kNeutral, kFreeCoast };

[[nodiscard]] constexpr const char* reference_kind_name(ReferenceKind k) noexcept {
  switch (k) {
    case ReferenceKind::kLoadSignal:
      return "load_signal";
    case ReferenceKind::kEMachineSole:
      return "e_machine_sole";
    case ReferenceKind::kNeutral:
      return "neutral";
    case ReferenceKind::kFreeCoast:
      return "free_coast";
    case ReferenceKind::kNone:
      break;
  }
  return "none";
}

/// How the vehicle's clutch/neutral flags are read (set by the daemon from can.signals / can.load_reference).
struct LoadReferenceParams {
  bool sole_flag_bound = false;    ///< can.signals.em_sole_load mapped: it overrides e_machine.sole_load
  bool neutral_bound = false;      ///< can.signals.neutral mapped
  bool load_signal_bound = false;  ///< can.signals.load_torque mapped (a dynamometer: no free coast-down)
  double accessory_nm = 3.0;       ///< prior mean of the accessories' torque with the driveline open (N m)
  double accessory_sd_nm = 2.0;    ///< its 1σ (N m)
  double load_sd_nm = 0.5;      ///< 1σ of a measured load / machine torque (set from fusion.can_load_sd_nm)
  double fuel_max_sd_nm = 3.0;  ///< the fuel model learns only from references at most this uncertain (N m)
  /// Free coast-down recognised from the crank and the fuel alone (AnglePipeline::detect_free_coast): no
  /// flag mapped, no machine, no load signal.
  bool free_coast = true;
  double free_coast_step_min = 0.6;  ///< crank's deceleration step at cut-off entry / modelled ΔT_ind (-)
  double free_coast_step_max = 1.6;
  double free_coast_decel_min = 0.55;  ///< coast's J θ̈ / (T_motored − friction − accessories) (-)
  double free_coast_decel_max = 1.8;
  double free_coast_decel_change = 0.15;  ///< largest change of J θ̈ from one coast cycle to the next (-)
  double free_coast_idle_map_rise_pa = 10e3;  ///< the coast's idle ends when MAP rises this much (Pa)
};

/// The load at one instant: the net load of fold_e_machine plus what fixes it and how well.
struct LoadReference {
  NetLoad net{};  ///< T_net (known: every input valid and the kind is not kNone)
  ReferenceKind kind = ReferenceKind::kNone;
  double sd_nm = 0.0;  ///< 1σ of net.torque_nm as a reference (N m)
};

/// What fixed the load of one 720° window, for the learners (AnglePipeline::cycle_reference).
struct CycleReference {
  ReferenceKind kind = ReferenceKind::kNone;
  double sd_nm = 0.0;  ///< 1σ of the window's load as a reference (N m)
  bool ok = false;     ///< a reference: known load at every tooth of the window, one kind throughout
};

/// Whether the machine is the only load now: the flag when mapped (stale or absent: not sole), else the
/// static configuration.
[[nodiscard]] inline bool machine_is_sole_load(const EMachineParams& em, const LoadReferenceParams& p,
                                               const EngineSignals& sig) noexcept {
  if (!em.bound) return false;
  return p.sole_flag_bound ? sig.em_sole_load_valid && sig.em_sole_load : em.sole_load;
}

/// The one decision of what fixes the load (see the header comment). Real-time safe.
[[nodiscard]] inline LoadReference classify_load(const EMachineParams& em, const LoadReferenceParams& p,
                                                 const EngineSignals& sig) noexcept {
  LoadReference r;
  const bool flagged = p.sole_flag_bound || p.neutral_bound;  // a vehicle: accessories act
  const double acc = flagged ? p.accessory_nm : 0.0;
  const double acc_sd = flagged ? p.accessory_sd_nm : 0.0;
  EMachineParams e = em;
  e.sole_load = machine_is_sole_load(em, p, sig);
  r.net = fold_e_machine(e, sig.load_torque_nm, sig.load_torque_valid, sig.em_torque_nm, sig.em_torque_valid);
  if (e.sole_load) {
    r.kind = ReferenceKind::kEMachineSole;
    r.net.torque_nm += acc;
    r.sd_nm = std::hypot(p.load_sd_nm, acc_sd);
    return r;
  }
  if (sig.load_torque_valid && std::isfinite(sig.load_torque_nm)) {
    r.kind = ReferenceKind::kLoadSignal;
    r.sd_nm = p.load_sd_nm;
    return r;
  }
  if (p.neutral_bound && sig.neutral_valid && sig.neutral) {
    r.kind = ReferenceKind::kNeutral;
    r.net.torque_nm = acc - r.net.em_crank_nm;
    r.net.known = !em.bound || r.net.em_valid;
    r.sd_nm = std::hypot(em.bound ? p.load_sd_nm : 0.0, acc_sd);
    return r;
  }
  r.net.known = false;  // clutch closed, no load signal: the load is unknown
  return r;
}

}  // namespace torqued
