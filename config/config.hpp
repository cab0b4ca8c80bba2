#pragma once
// The validated, immutable description of one installation (docs/conventions.md habit 7).
// Filled only by config_loader.cpp from YAML, every key declared once in config_schema.cpp (type, default,
// bounds, unit, description). Defaults here are the schema's defaults. Paths are absolute after loading
// (relative paths in the YAML resolve against the YAML file's directory). Not used on the real-time path:
// size everything from it before the threads start.
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "crank_decoder.hpp"  // DecoderParams (io/, header only)
#include "engine_geometry.hpp"
#include "fuel_torque.hpp"  // FuelTorqueParams
#include "params.hpp"

namespace torqued {

enum class EdgeBackend : std::uint8_t { kFile, kGpio, kCanEncoder };
enum class EdgeFormat : std::uint8_t { kCsv, kList };
enum class CanBackend : std::uint8_t { kFile, kSocketCan };
enum class SchedPolicy : std::uint8_t { kFifo, kOther };
enum class Reliability : std::uint8_t { kReliable, kBestEffort };
enum class ReplayMode : std::uint8_t { kFast, kPaced };
/// Fast replay's threads (replay.fast_threads): auto = 3 when the process may run on at least 2 CPUs, else 1.
enum class FastThreads : std::uint8_t { kAuto, kOne, kThree };
enum class LogLevel : std::uint8_t { kTrace, kDebug, kInfo, kWarn, kError, kCritical, kOff };

/// Number of CAN quantities of EngineSignals; `CanSignalsConfig::signals` is indexed by torqued::Quantity
/// (io/signal_store.hpp: map, maf, intake_temp, oil_temp, throttle, lambda, spark_advance, fuel_mass,
/// fuel_cutoff, load_torque, em_torque, em_sole_load, neutral — the YAML keys under can.signals, same order).
inline constexpr std::size_t kCanQuantityCount = 13;
/// Index of em_torque (the electric machine's torque, hybrid input) in `CanSignalsConfig::signals`.
inline constexpr std::size_t kCanEmTorque = 10;
/// Indices of the vehicle flags em_sole_load (the machine is the only load) and neutral (clutch open).
inline constexpr std::size_t kCanEmSoleLoad = 11;
inline constexpr std::size_t kCanNeutral = 12;
/// YAML name of quantity index i under `can.signals` ("map", "maf", ...); "" when out of range.
[[nodiscard]] std::string_view can_quantity_name(std::size_t i) noexcept;

/// Crank wheel and channel names (names match the header of the edge CSV).
struct WheelConfig {
  WheelGeometry geometry;               ///< YAML: teeth (positions), missing, tooth_angles_deg, edge
  std::string crank_channel = "crank";  ///< edge CSV column of the crank sensor
  std::string cam_channel = "cam";      ///< edge CSV column of the cam sensor ("" = no cam: 360° only)
  bool cam_rising_edge = true;          ///< cam edge that marks the phase (YAML cam_edge: rising|falling)
  /// Decoder tuning (YAML wheel.decoder.*). Its cam_rising / use_cam are set from cam_edge / cam_channel; the
  /// channel indices are assigned by the backend factory.
  DecoderParams decoder;
};

struct EdgeInputConfig {
  EdgeBackend backend = EdgeBackend::kFile;
  std::string path;                          ///< edge capture file (backend file), absolute after loading
  EdgeFormat format = EdgeFormat::kCsv;      ///< csv = logic-analyzer export, list = one edge time per line
  std::string gpio_chip = "/dev/gpiochip0";  ///< backend gpio
  int gpio_crank_line = 0;                   ///< GPIO line offset of the crank sensor
  int gpio_cam_line = -1;                    ///< GPIO line offset of the cam sensor (-1 = none)
  std::uint32_t encoder_can_id = 0x300;      ///< backend can_encoder: CAN id of the tooth-timestamp frames
  double timeout_s = 0.5;  ///< no crank edge for this long: DaemonStatus EDGE_TIMEOUT flag (s)
};

struct CanInputConfig {
  CanBackend backend = CanBackend::kFile;
  std::string path;                ///< candump -l log (backend file), absolute after loading
  std::string interface = "can0";  ///< SocketCAN interface (backend socketcan)
  bool fd = false;                 ///< enable CAN FD frames
  double time_offset_s = 0.0;      ///< added to CAN timestamps to put them on the edge clock (s)
};

struct InputsConfig {
  EdgeInputConfig edges;
  CanInputConfig can;
  /// File inputs (io/time_sanity.hpp): a record more than this ahead of the previous one starts a candidate
  /// run; it is dropped as an outlier unless time_rebase_records records in step follow it (s).
  double max_time_jump_s = 10.0;
  int time_rebase_records = 8;  ///< records in step after a jump that prove a genuine clock jump (re-base)
};

/// Where a quantity comes from: DBC message + signal. Empty message = not mapped (estimators see it invalid).
struct SignalMapping {
  std::string message;   ///< DBC message name (BO_)
  std::string signal;    ///< DBC signal name (SG_); its DBC unit is converted to SI by the signal store
  int timeout_ms = 100;  ///< older than this = invalid (ms)
  [[nodiscard]] bool mapped() const noexcept { return !message.empty(); }
};

/// Hybrid input (YAML can.e_machine): how can.signals.em_torque maps onto the crank
/// (estimators/core/e_machine.hpp).
struct EMachineConfig {
  double ratio = 1.0;  ///< machine speed / crank speed: T_em,crank = sign · ratio · T_em (-)
  int sign = 1;        ///< +1: em_torque positive when the machine drives the crank; −1: when it brakes it
  bool sole_load = false;  ///< the machine is the only load on the crank (bench motoring, clutch open)
};

/// Vehicle load references (YAML can.load_reference; estimators/core/load_reference.hpp): used only when
/// can.signals.em_sole_load or can.signals.neutral is mapped.
struct LoadReferenceConfig {
  double accessory_nm = 3.0;     ///< prior mean of the accessories' torque with the driveline open (N m)
  double accessory_sd_nm = 2.0;  ///< its 1σ (N m)
  double fuel_max_sd_nm = 3.0;   ///< the fuel model learns only from references at most this uncertain (N m)
  bool free_coast = true;        ///< recognise a free coast-down (clutch open) without a flag
  double free_coast_step_min = 0.6;  ///< its deceleration step at cut-off entry / modelled ΔT_ind (-)
  double free_coast_step_max = 1.6;
  double free_coast_decel_min = 0.55;  ///< its J θ̈ / free engine's (T_motored − friction − accessories)
  double free_coast_decel_max = 1.8;
  double free_coast_decel_change = 0.15;       ///< largest change of a free coast's J θ̈ between cycles (-)
  double free_coast_idle_map_rise_kpa = 10.0;  ///< the coast's idle ends when MAP rises this much (kPa)
};

struct CanSignalsConfig {
  std::string dbc;                                         ///< DBC file, absolute after loading ("" = none)
  std::array<SignalMapping, kCanQuantityCount> signals{};  ///< indexed by static_cast<size_t>(Quantity)
  EMachineConfig e_machine;
  LoadReferenceConfig load_reference;
};

template <class Params>
struct EstimatorToggle {
  bool enabled = true;
  Params params{};
};

/// The enabled flags of uio/sliding_mode/dirty_diff/adaptive are mirrored into time_pipeline.{uio,...}.
struct EstimatorsConfig {
  TimePipelineParams time_pipeline;  ///< time-triggered pipeline step (Na estimators run on it)
  PreprocessParams preprocess;       ///< per-tooth speed/acceleration pre-processing (angle estimators)
  FusionParams fusion;               ///< fused best brake torque
  EstimatorToggle<UioParams> uio;
  EstimatorToggle<SlidingModeParams> sliding_mode;
  EstimatorToggle<DirtyDiffParams> dirty_diff;
  EstimatorToggle<AdaptiveParams> adaptive;
  EstimatorToggle<KalmanParams> kalman;
  EstimatorToggle<FourierParams> fourier;
  EstimatorToggle<EnergiesParams> energies;
  EstimatorToggle<FrictionParams> friction;
  EstimatorToggle<CylinderParams> cylinder;
  EstimatorToggle<ToothLearnParams> tooth_learn;
  /// YAML estimators.tooth_learn.max_correction_deg: largest |correction| a stored tooth table may hold
  /// (deg); a larger one is a corrupt file, refused at load (learned/state_store.cpp) and relearned. Physics,
  /// not the simulator: ISO 1328-1's coarsest accuracy grade (12) allows a cumulative pitch deviation F_p of
  /// about 0.28 mm on a 60-tooth module-3 wheel (r = 90 mm), 0.18 deg; flywheel runout limits of about 0.08
  /// mm add 0.05 deg. 0.5 deg leaves margin for learning noise, 6x below half a 60-tooth pitch (3 deg).
  double tooth_max_correction_deg = 0.5;
  FuelTorqueParams fuel;  ///< fuel-based indicated torque (learned efficiency; no-load brake torque)
  double default_oil_temp_c = 90.0;  ///< friction law's oil temperature until OilTemp arrives on CAN (°C)
};

/// QoS of one DDS topic (defined in one place; the daemon maps it onto dds_qos_t).
struct TopicQos {
  Reliability reliability = Reliability::kReliable;
  int history_depth = 8;  ///< KEEP_LAST depth
  int deadline_ms = 0;    ///< 0 = no deadline
  int lease_ms = 0;       ///< liveliness (automatic) lease, 0 = infinite
};

struct DdsConfig {
  int domain_id = 0;
  std::string topic_prefix = "torque";  ///< topic names are <prefix>/<Type>, e.g. torque/EngineTorque
  int engine_id = 1;                    ///< @key of every sample (uint16 on the wire)
  // Defaults equal idl/qos.hpp DdsSettings::default_qos().
  TopicQos engine_torque{Reliability::kReliable, 64, 1000, 1000};
  TopicQos estimator_torque{Reliability::kReliable, 1024, 1000, 1000};  // per key (idl/qos.hpp: why 1024)
  TopicQos cylinder_torque{Reliability::kReliable, 16, 1000, 1000};
  TopicQos crank_state{Reliability::kBestEffort, 1, 1000, 1000};
  TopicQos status{Reliability::kReliable, 4, 3000, 1000};
  int crank_state_decimation = 10;     ///< CrankState every n-th tooth
  int time_estimator_decimation = 10;  ///< EstimatorTorque of the time methods every n-th time step
  int tooth_estimator_decimation =
      2;  ///< EstimatorTorque of the in-cycle Kalman/Fourier every n-th tooth (0 = off)
  double status_period_s = 1.0;  ///< DaemonStatus (and sd_notify STATUS=) period (s)
};

/// Scheduling of one daemon thread.
struct ThreadConfig {
  SchedPolicy policy = SchedPolicy::kFifo;
  int priority = 50;      ///< SCHED_FIFO priority 1..99 (ignored for policy other)
  std::vector<int> cpus;  ///< CPU affinity list (empty = any CPU)
};

struct RealtimeConfig {
  ThreadConfig angle{SchedPolicy::kFifo, 80, {}};
  ThreadConfig time{SchedPolicy::kFifo, 70, {}};
  ThreadConfig source{SchedPolicy::kFifo, 85, {}};
  ThreadConfig publisher{SchedPolicy::kFifo, 60, {}};  // below the pipelines; not allocation-free (DDS)
  bool lock_memory = true;     ///< mlockall(MCL_CURRENT|MCL_FUTURE) before the threads start
  bool lock_on_fault = false;  ///< ... with MCL_ONFAULT: lock pages when first touched, not every mapped page
  bool require_rt = false;     ///< refuse to start when SCHED_FIFO / mlockall are not permitted (else warn)
  int publisher_spin_us =
      150;  ///< paced replay: publisher wakes at the next edge's due time and polls this long
};

struct OutputConfig {
  std::string record_dir;  ///< write estimate CSVs here ("" = no recording), absolute after loading
  std::string state_dir = "/var/lib/torqued";  ///< learned state (friction, tooth corrections)
  std::string table_dir;  ///< start-up table cache ("" = <state_dir>/tables or the user cache, "off" = none)
};

struct ReplayConfig {
  ReplayMode mode = ReplayMode::kFast;
  double speed = 1.0;  ///< paced replay speed factor (2 = twice real time)
  /// Paced replay of files that does not loop: exit (0) once the recording is consumed (= --exit-when-done).
  bool exit_when_done = true;
  bool loop = false;  ///< paced replay of files: start the recording again at its end (io/looping_source.hpp)
  /// Fast replay: 1 = everything on the chain's thread; 3 = a reader and a recording writer beside it.
  FastThreads fast_threads = FastThreads::kAuto;
};

/// Prometheus exposition endpoint (service/metrics.hpp), served by its own threads, never the real-time ones.
struct MetricsConfig {
  bool enabled = false;
  std::string address = "127.0.0.1:9464";  ///< HOST:PORT to listen on (loopback unless you mean otherwise)
};

struct LoggingConfig {
  LogLevel level = LogLevel::kInfo;
};

/// The whole installation. Build it with load_config() (config_loader.hpp); treat it as const afterwards.
struct Config {
  std::string source_file;  ///< absolute path of the YAML it came from ("" = built-in defaults)
  EngineGeometry engine;    ///< YAML tdc_offset_deg is stored as tdc_offset_rad
  WheelConfig wheel;
  InputsConfig inputs;
  CanSignalsConfig can;
  EstimatorsConfig estimators;
  DdsConfig dds;
  RealtimeConfig realtime;
  OutputConfig output;
  ReplayConfig replay;
  MetricsConfig metrics;
  LoggingConfig logging;
};

}  // namespace torqued
