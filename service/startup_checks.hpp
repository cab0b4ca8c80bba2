#pragma once
// What the daemon refuses at start beyond the configuration loader, checked without starting it (torqued
// --check-config, which the service's ExecStartPre relies on): the file inputs open and carry what the
// configuration names (edge CSV header with the crank/cam columns, a readable candump log). DDS names and
// value ranges that make clocks or rates non-finite are the loader's own checks (config/config_loader.cpp
// check_config_physics, the schema bounds), so the daemon and --check-config share them.
#include <string>
#include <vector>

#include "config.hpp"

namespace torqued {

/// Start-up refusals of `cfg` found by opening its file inputs ("inputs.edges: FILE:LINE: ..."); empty when
/// the daemon would start. Live backends (GPIO, SocketCAN) are not opened here.
[[nodiscard]] std::vector<std::string> startup_problems(const Config& cfg);

}  // namespace torqued
