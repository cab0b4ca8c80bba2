#pragma once
// Hybrid input: the electric machine's torque on the crankshaft, from CAN, folded into the
// net load every balance sees. Newton on the crank with the machine on it:
//   J θ̈ = T_ind − T_fric − T_load + T_em,crank,   T_em,crank = sign · ratio · T_em,CAN
// so the angle chain, the time chain and the friction learner keep their one-load form J θ̈ = T_ind − T_fric −
// T_net with the net load T_net = T_load − T_em,crank (absorbing positive). T_em,crank is positive when the
// machine drives the crank (motoring, boost), negative when it brakes it (generating). With `sole_load` the
// machine is the only load (a bench motoring the engine, a hybrid with the clutch to the wheels open): T_net
// = −T_em,crank and the energy balance needs no dynamometer. Header only, real-time safe (no allocation, no
// branch on anything but the arguments).
#include <cmath>

#include "samples.hpp"

namespace torqued {

/// How the machine's CAN torque maps onto the crank. `bound` is set by the daemon when can.signals.em_torque
/// is mapped; when false the fold is the identity (the load signal alone, as before the hybrid input
/// existed).
struct EMachineParams {
  bool bound = false;  ///< em_torque is mapped to a CAN signal
  double ratio = 1.0;  ///< machine speed / crank speed: T_em,crank = ratio · T_em (-)
  double sign =
      1.0;  ///< +1: the CAN value is positive when the machine drives the crank, −1: when it brakes it
  bool sole_load = false;  ///< the machine is the only load on the crank (no other load torque acts)
};

/// The net load on the crank at one instant, and whether the balances may use it.
struct NetLoad {
  double torque_nm = 0.0;  ///< T_net = T_load − T_em,crank (N m), absorbing positive
  double em_crank_nm =
      0.0;                ///< T_em,crank (N m), driving positive (0 when the machine is not bound or stale)
  bool known = false;     ///< every input it rests on is valid: the balances may use torque_nm
  bool em_valid = false;  ///< the machine's torque is bound and fresh
  bool em_stale = false;  ///< the machine is bound but its value is stale or rejected: what rests on it holds
};

/// T_em,crank of a CAN machine torque (N m). Real-time safe.
[[nodiscard]] constexpr double em_crank_torque_nm(const EMachineParams& p, double em_can_nm) noexcept {
  return p.sign * p.ratio * em_can_nm;
}

/// Folds the machine torque into the load (see the header comment). Not bound: the load signal unchanged.
/// Bound: sole_load → T_net = −T_em,crank, known when the machine's value is; otherwise T_net = T_load −
/// T_em,crank, known when both are. A stale (or rejected, non-finite) machine value makes T_net unknown and
/// sets em_stale, exactly as a stale load signal does (the energy balance then holds with STALE_CAN).
/// Real-time safe.
[[nodiscard]] inline NetLoad fold_e_machine(const EMachineParams& p, double load_nm, bool load_valid,
                                            double em_can_nm, bool em_valid) noexcept {
  NetLoad n;
  const bool load_ok = load_valid && std::isfinite(load_nm);
  if (!p.bound) {
    n.torque_nm = load_nm;
    n.known = load_ok;
    return n;
  }
  n.em_valid = em_valid && std::isfinite(em_can_nm);
  n.em_stale = !n.em_valid;
  n.em_crank_nm = n.em_valid ? em_crank_torque_nm(p, em_can_nm) : 0.0;
  if (p.sole_load) {
    n.torque_nm = -n.em_crank_nm;
    n.known = n.em_valid;
  } else {
    n.torque_nm = (load_ok ? load_nm : 0.0) - n.em_crank_nm;
    n.known = n.em_valid && load_ok;
  }
  return n;
}

/// The same on the CAN snapshot the estimators get.
[[nodiscard]] inline NetLoad fold_e_machine(const EMachineParams& p, const EngineSignals& sig) noexcept {
  return fold_e_machine(p, sig.load_torque_nm, sig.load_torque_valid, sig.em_torque_nm, sig.em_torque_valid);
}

}  // namespace torqued
