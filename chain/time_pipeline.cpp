#include "time_pipeline.hpp"

#include <cmath>
#include <numbers>

#include "crank_kinematics.hpp"

namespace torqued {

double mean_inertia_kgm2(const EngineGeometry& geometry) noexcept {
  const CrankKinematics kin(geometry);
  constexpr int kPoints = 1440;
  double sum = 0.0;
  for (int i = 0; i < kPoints; ++i) sum += kin.inertia(4.0 * std::numbers::pi * i / kPoints);
  return sum / kPoints;
}

namespace {
double pick_inertia(const TimePipelineParams& p, const EngineGeometry& g) noexcept {
  return p.inertia_kgm2 > 0.0 ? p.inertia_kgm2 : mean_inertia_kgm2(g);
}
}  // namespace

TimePipeline::TimePipeline(const TimePipelineParams& params, const TimeEstimatorParams& est,
                           const EngineGeometry& geometry) noexcept
    : params_(params),
      inertia_kgm2_(pick_inertia(params, geometry)),
      tracker_(params.cycle_averaged_speed
                   ? 4.0 * std::numbers::pi
                   : 4.0 * std::numbers::pi / static_cast<double>(geometry.cylinders)),
      uio_(est.uio, inertia_kgm2_, params.step_s),
      sliding_(est.sliding_mode, inertia_kgm2_, params.step_s),
      dirty_(est.dirty_diff, inertia_kgm2_, params.step_s),
      adaptive_(est.adaptive, inertia_kgm2_, params.step_s) {
  reset();
}

void TimePipeline::reset() noexcept {
  tracker_.reset();
  uio_.reset();
  sliding_.reset();
  dirty_.reset();
  adaptive_.reset();
  has_last_ = false;
  out_ = TimePipelineOutput{};
}

void TimePipeline::on_tooth(const ToothSample& tooth) noexcept { tracker_.update(tooth); }

const TimePipelineOutput& TimePipeline::step(std::int64_t t_ns, const EngineSignals& signals) noexcept {
  TimeSample s;
  s.t_ns = t_ns;
  s.dt_s = has_last_ ? 1e-9 * static_cast<double>(t_ns - last_t_ns_) : params_.step_s;
  // Mean speed: invalid until the decoder is synced and the window is covered; stale when no tooth came
  // within speed_timeout_s (engine stopped or edge source lost).
  s.speed_rad_s = tracker_.speed_rad_s();
  if (!tracker_.valid()) {
    s.speed = InputStatus::kInvalid;
  } else if (1e-9 * static_cast<double>(t_ns - tracker_.t_ns()) > params_.speed_timeout_s) {
    s.speed = InputStatus::kStale;
  } else {
    s.speed = InputStatus::kOk;
  }
  // The signal store already turned time-outs into valid == false; we cannot tell stale from rejected here,
  // so a missing CAN signal is reported as stale (the common cause: CAN lost).
  // Hybrid input: the net load T_load − T_em,crank (e_machine.hpp); a stale machine value makes it stale. On
  // a vehicle the clutch / neutral flags decide whether anything fixes it (classify_load,
  // load_reference.hpp).
  const NetLoad net = classify_load(e_machine_, load_ref_, signals).net;
  s.load_torque_nm = net.torque_nm;
  s.load = net.known ? InputStatus::kOk : InputStatus::kStale;
  s.maf_kg_s = signals.maf_kg_s;
  s.maf = signals.maf_valid ? InputStatus::kOk : InputStatus::kStale;
  return step(s);
}

const TimePipelineOutput& TimePipeline::step(const TimeSample& sample) noexcept {
  out_.input = sample;
  if (!(sample.dt_s > 0.0))
    out_.input.dt_s = params_.step_s;  // repeated or reordered tick: use the nominal step
  last_t_ns_ = sample.t_ns;
  has_last_ = true;
  auto run = [&](bool enabled, auto& est, TorqueEstimate& dst) {
    if (enabled) {
      est.update(out_.input);
      dst = est.estimate();
    } else {
      dst = TorqueEstimate{sample.t_ns, 0.0, 0.0, Health::kDisabled};
    }
  };
  run(params_.uio, uio_, out_.uio);
  run(params_.sliding_mode, sliding_, out_.sliding_mode);
  run(params_.dirty_diff, dirty_, out_.dirty_diff);
  run(params_.adaptive, adaptive_, out_.adaptive);
  out_.theta_si = adaptive_.theta_si();
  out_.lambda_min_p = adaptive_.lambda_min_p();
  return out_;
}

}  // namespace torqued
