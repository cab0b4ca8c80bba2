#pragma once
// The inputs of a run as the configuration names them: edge source, CAN source, DBC and the stage settings.
// One opening rule for the daemon (every mode) and torque-accuracy --recording, so both see the same inputs.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dbc.hpp"
#include "source.hpp"
#include "stage_settings.hpp"

namespace torqued {

struct Config;

struct RunInputs {
  StageSettings settings;
  std::unique_ptr<EdgeSource> edges;
  std::unique_ptr<CanSource> can;         ///< null: no CAN input configured
  std::optional<DbcDatabase> dbc;         ///< nullopt: no DBC configured
  std::int64_t can_offset_ns = 0;         ///< added to every CAN frame time (inputs.can.time_offset)
  std::vector<std::string> dbc_warnings;  ///< accepted DBC with problems (file:line each), for the log
  std::string error;                      ///< "<config key>: <why>" when an input could not be opened

  [[nodiscard]] bool ok() const noexcept { return error.empty(); }
  [[nodiscard]] const DbcDatabase* dbc_ptr() const noexcept { return dbc ? &*dbc : nullptr; }
};

[[nodiscard]] RunInputs open_inputs(const Config& cfg);

/// What the sources say about their input once they have ended (file:line of bad lines, an input with no
/// record at all), one log line each. Either source may be null. Call once the sources have ended.
[[nodiscard]] std::vector<std::string> input_problems(const EdgeSource* edges, const CanSource* can);

}  // namespace torqued
