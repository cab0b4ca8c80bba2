#pragma once
// Writes a simulation in the project's input formats (docs/io.md "Sources", docs/simulator.md §7) and its
// truth.
#include <filesystem>
#include <string>

#include "engine_sim.hpp"

namespace torqued::sim {

/// candump times are 1700000000 s + simulation time (config key inputs.can.time_offset_s = -1700000000).
inline constexpr std::int64_t kCandumpEpochS = 1700000000;

[[nodiscard]] std::string edges_csv(const SimOutput& out);    ///< "Time [s],crank,cam", 9 decimals
[[nodiscard]] std::string candump_log(const SimOutput& out);  ///< candump -l lines on can0
[[nodiscard]] std::string truth_tooth_csv(const SimOutput& out, const Scenario& sc);
[[nodiscard]] std::string truth_cycle_csv(const SimOutput& out, const Scenario& sc);
[[nodiscard]] std::string tooth_errors_csv(const SimOutput& out);
[[nodiscard]] std::string engine_yaml(const Scenario& sc);  ///< engine: and wheel: sections of the config

/// A torqued configuration replaying edges.csv / can.log / demo.dbc of the same directory: engine section
/// from `engine` (the spec sheet a user would configure, not the simulator's truth), wheel from `sc`, every
/// CAN signal of demo.dbc mapped; the load-torque signal only when `load_signal` (dynamometer) is set.
[[nodiscard]] std::string torqued_config_yaml(const EngineGeometry& engine, const Scenario& sc,
                                              bool load_signal);
/// The same; a vehicle scenario (VehicleSim) never maps a load signal, and maps VEH_1.ClutchOpen (as
/// em_sole_load with a machine, as neutral without) only when `vehicle_flag`.
[[nodiscard]] std::string torqued_config_yaml(const EngineGeometry& engine, const Scenario& sc,
                                              bool load_signal, bool vehicle_flag);

/// write_outputs() plus demo.dbc, torqued.yaml (with the load signal; a vehicle scenario: with its clutch
/// flag) and torqued_noload.yaml (vehicle case; a vehicle scenario: no clutch flag either), configured with
/// `engine` (spec sheet). Throws std::runtime_error naming the file on failure.
void write_recording(const SimOutput& out, const Scenario& sc, const EngineGeometry& engine,
                     const std::filesystem::path& dir);

/// Writes edges.csv, can.log, truth_tooth.csv, truth_cycle.csv, engine.yaml, tooth_errors.csv into `dir`
/// (created if needed). Throws std::runtime_error naming the file on failure.
void write_outputs(const SimOutput& out, const Scenario& sc, const std::filesystem::path& dir);
/// Writes `text` to `path`, throwing std::runtime_error naming the file on failure.
void write_text_file(const std::filesystem::path& path, const std::string& text);

}  // namespace torqued::sim
