#pragma once
// The "unseen engines" test bed (docs/simulator.md §9): a fixed list of seeded engines whose true parameters
// are drawn from plausible ranges around a spec sheet, so that estimators are evaluated on engines they were
// not tuned on. Each engine has a spec sheet (what a user configures: bore, stroke, rod, compression ratio,
// firing order, wheel, catalogue inertia and oscillating mass) and a hidden truth (inertia ±10 %, oscillating
// mass ±10 %, friction level ±40 % and shape, combustion phasing and duration, heat loss, valve timing incl.
// an EVO late enough to overlap the next cylinder's compression window, tooth errors 0.02-0.1°). 3, 4 and 6
// cylinders; 60-2 and 36-1 wheels. Engines are split into "tuning" engines (may be looked at while choosing
// estimator tunings) and "report" engines (only for the accuracy table). docs/simulator.md §7.
#include <string>
#include <utility>
#include <vector>

#include "engine_sim.hpp"

namespace torqued::sim {

struct BedEngine {
  std::string name;
  bool report = false;    ///< false: tuning engine
  EngineGeometry spec{};  ///< spec-sheet geometry handed to the estimators (inertia, m_osc catalogue values)
  Scenario truth{};       ///< hidden truth: engine, wheel, combustion, friction, sensors (schedules empty)
};

/// The fixed list (deterministic: drawn from fixed seeds).
[[nodiscard]] const std::vector<BedEngine>& unseen_engines();
/// The prior-calibration set: tuning-role engines drawn like the fixed list from other seeds (four each of
/// I3, I4 and I6, half on 60-2 and half on 36-1 wheels). They are never scored in an accuracy table: they
/// only measure how far the generic priors (the friction correlation, the fuel model's efficiency) sit from
/// engines, so that the priors' claimed 1σ rests on more than the three tuning engines (torque-accuracy
/// --bed-priors; docs/angle_pipeline.md "Calibrating the priors").
[[nodiscard]] const std::vector<BedEngine>& calibration_engines();
/// The engine of the fixed list named `name`, or nullptr.
[[nodiscard]] const BedEngine* unseen_engine(const std::string& name);

/// Learning recording: plateaus, idle, an overrun (fuel cut-off with the dyno holding speed) and a free
/// fuel cut-off coast-down; the load signal is on CAN. The estimator state learned here is carried into the
/// evaluated recording, as a daemon in service does.
[[nodiscard]] Scenario bed_learning_run(const BedEngine& e);
/// One-point learning recording (the vehicle that met a load reference once): idle (free engine), the
/// dyno-held overrun in fuel cut-off as in bed_learning_run(), then firing at ONE operating point (2500 rpm,
/// 60 kPa) with the load signal on CAN. What it teaches must carry to the rest of the map.
[[nodiscard]] Scenario bed_one_point_learning_run(const BedEngine& e);
/// Motoring recording (hybrid input): fuel cut-off throughout, closed throttle, the load (an electric machine
/// when the scenario has one) holds 1000, 1500, ... 4000 rpm plateaus: the machine motors the engine.
[[nodiscard]] Scenario bed_motoring_run(const BedEngine& e);
/// Vehicle recordings (VehicleSim; docs/simulator.md §7). No load signal on CAN; VEH_1.ClutchOpen is sent (a
/// configuration may leave it unmapped). Vehicle only: idle in neutral, driving 1000-3000 rpm at 35-92 kPa in
/// gear, an overrun (fuel cut-off) in gear, a coast-down in neutral with the fuel cut. `short_run`: a few
/// seconds.
[[nodiscard]] Scenario bed_vehicle_run(const BedEngine& e, bool short_run = false);
/// Hybrid (machine on the crank, ratio 1): standstill charging with the clutch open (the machine holds speed,
/// after a motored start), at 3 speed/torque points (10.5 s; short: 3 s), then driving with the clutch
/// closed, machine boost and generation, an overrun in gear. `t_drive_s` (may be null): when the clutch
/// closes.
[[nodiscard]] Scenario bed_hybrid_run(const BedEngine& e, bool short_run = false,
                                      double* t_drive_s = nullptr);
/// Fresh start without any fuel cut-off (a bench that never overruns, a vehicle's first minute): dyno-held
/// firing plateaus 1500-3200 rpm at 40-88 kPa (no two at the same load), 6 s each (short: 2 s) with 0.5 s
/// ramps, the last two at 1500 and 2200 rpm. 60 s (short: 20 s). `steady_s` (may be null): the steady parts
/// of the last two plateaus, [from, to) in s, where the in-cycle figures are scored.
[[nodiscard]] Scenario bed_firing_start_run(const BedEngine& e, bool short_run = false,
                                            std::vector<std::pair<double, double>>* steady_s = nullptr);
/// In-cycle regimes after a fresh start: bed_firing_start_run(short) (20 s, the tooth learner's recording),
/// 0.5 s more at its last plateau, then bed_eval_run() (10 s: speed ramps 1500-3500 rpm, throttle steps
/// 35-90 kPa, a fuel cut-off at 3500 rpm with the dyno dragging the engine towards 2500 rpm, 1 s, and its
/// exit). `transient_s`: [20.5, 27) s, eval 0-6.5 s (up to the cut-off entry); `cutoff_s`: [26.8, 30.5) s,
/// 0.2 s before the entry to the end, 2.5 s after the exit.
[[nodiscard]] Scenario bed_incycle_regimes_run(const BedEngine& e, std::pair<double, double>* transient_s,
                                               std::pair<double, double>* cutoff_s);
/// A fresh start that ramps from idle as a driven engine does, the demo scenario's first 16 s as a SHAPE (its
/// speed and MAP schedule, not its engine): idle at 800 rpm (idle controller, free engine) to 3 s, then
/// dyno-held ramps to 1500, 2500 and 3500 rpm (9.4 s) with throttle steps 35-90 kPa, a fuel cut-off at 3500
/// rpm (11.1-11.9 s, closed throttle) and 2000 rpm at 45-80 kPa; the spark follows the simulator's map of
/// speed and MAP. 16 s. `ramp_s` (may be null): [0, 15) s, where the young wheel table meets the ramp (scored
/// from the moment the tooth learner's table is first applied, as the observers are valid from then on).
[[nodiscard]] Scenario bed_ramp_start_run(const BedEngine& e, std::pair<double, double>* ramp_s);
/// Evaluated recording: steady plateaus at several speeds and loads, throttle and load transients, a fuel
/// cut-off. `short_run`: a 4 s subset (ctest).
[[nodiscard]] Scenario bed_eval_run(const BedEngine& e, bool short_run = false);

}  // namespace torqued::sim
