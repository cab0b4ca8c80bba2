// estimators/core/load_reference.hpp: what fixes the load on the crank on a vehicle (clutch / neutral flags),
// each case against its analytic value (exact, 1e-12): the flag switches the machine between the only load
// and one input among unknown ones, a fuel cut-off with the clutch closed and no load signal is no reference,
// neutral carries the accessory prior and its 1σ.
#include <gtest/gtest.h>

#include <cmath>

#include "load_reference.hpp"

namespace torqued {
namespace {

EMachineParams machine(bool static_sole) {
  EMachineParams p;
  p.bound = true;
  p.ratio = 2.0;
  p.sole_load = static_sole;
  return p;
}
LoadReferenceParams flags(bool sole, bool neutral) {
  LoadReferenceParams p;
  p.sole_flag_bound = sole;
  p.neutral_bound = neutral;
  p.accessory_nm = 3.0;
  p.accessory_sd_nm = 2.0;
  p.load_sd_nm = 0.5;
  return p;
}
EngineSignals em_signals(double em_nm, bool clutch_open) {
  EngineSignals s;
  s.em_torque_nm = em_nm;
  s.em_torque_valid = true;
  s.em_sole_load = clutch_open;
  s.em_sole_load_valid = true;
  return s;
}

TEST(LoadReference, FlagSwitchesTheMachineBetweenSoleLoadAndUnknownLoad) {
  // GIVEN the flag mapped (it overrides the static sole_load = false) WHEN the clutch is open THEN T_net =
  // T_acc − ratio·T_em, 1σ = hypot(machine, accessories); WHEN closed THEN nothing fixes the load.
  const LoadReference open = classify_load(machine(false), flags(true, false), em_signals(-20.0, true));
  EXPECT_EQ(open.kind, ReferenceKind::kEMachineSole);
  EXPECT_TRUE(open.net.known);
  EXPECT_NEAR(open.net.torque_nm, 3.0 + 40.0, 1e-12);
  EXPECT_NEAR(open.sd_nm, std::hypot(0.5, 2.0), 1e-12);
  const LoadReference closed = classify_load(machine(true), flags(true, false), em_signals(-20.0, false));
  EXPECT_EQ(closed.kind, ReferenceKind::kNone);
  EXPECT_FALSE(closed.net.known);
}

TEST(LoadReference, StaleFlagIsNotSoleLoad) {
  EngineSignals s = em_signals(10.0, true);
  s.em_sole_load_valid = false;
  EXPECT_EQ(classify_load(machine(true), flags(true, false), s).kind, ReferenceKind::kNone);
}

TEST(LoadReference, StaticSoleLoadWithoutFlagsIsTheBenchAsBefore) {
  // GIVEN no flag mapped, static sole_load THEN T_net = −ratio·T_em exactly (no accessories on a bench).
  const LoadReference r = classify_load(machine(true), flags(false, false), em_signals(12.0, false));
  EXPECT_EQ(r.kind, ReferenceKind::kEMachineSole);
  EXPECT_NEAR(r.net.torque_nm, -24.0, 1e-12);
  EXPECT_NEAR(r.sd_nm, 0.5, 1e-12);
}

TEST(LoadReference, OverrunInGearWithoutLoadSignalIsNoReference) {
  // GIVEN a vehicle without machine, fuel cut-off, clutch closed (neutral flag clear), no load signal.
  EngineSignals s;
  s.fuel_cutoff = true;
  s.fuel_cutoff_valid = true;
  s.neutral = false;
  s.neutral_valid = true;
  const LoadReference r = classify_load(EMachineParams{}, flags(false, true), s);
  EXPECT_EQ(r.kind, ReferenceKind::kNone);
  EXPECT_FALSE(r.net.known);
  // Unmapped flags: the same.
  EXPECT_FALSE(classify_load(EMachineParams{}, flags(false, false), s).net.known);
}

TEST(LoadReference, NeutralCarriesTheAccessoryPrior) {
  EngineSignals s;
  s.neutral = true;
  s.neutral_valid = true;
  const LoadReference r = classify_load(EMachineParams{}, flags(false, true), s);
  EXPECT_EQ(r.kind, ReferenceKind::kNeutral);
  EXPECT_TRUE(r.net.known);
  EXPECT_NEAR(r.net.torque_nm, 3.0, 1e-12);
  EXPECT_NEAR(r.sd_nm, 2.0, 1e-12);
}

TEST(LoadReference, LoadSignalWinsOverNeutralAndFoldsTheMachine) {
  EngineSignals s = em_signals(5.0, false);
  s.load_torque_nm = 40.0;
  s.load_torque_valid = true;
  s.neutral = true;
  s.neutral_valid = true;
  const LoadReference r = classify_load(machine(false), flags(true, true), s);
  EXPECT_EQ(r.kind, ReferenceKind::kLoadSignal);
  EXPECT_NEAR(r.net.torque_nm, 40.0 - 10.0, 1e-12);
  EXPECT_NEAR(r.sd_nm, 0.5, 1e-12);
}

}  // namespace
}  // namespace torqued
