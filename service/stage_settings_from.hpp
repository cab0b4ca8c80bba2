#pragma once
// The wiring of the chains: the validated Config mapped onto the plain StageSettings the chains and stages
// are built from (chain/stage_settings.hpp). The only place where the configuration schema meets the chains.
#include "config.hpp"
#include "stage_settings.hpp"

namespace torqued {

/// Maps the validated Config onto StageSettings.
StageSettings stage_settings_from(const Config& cfg);

}  // namespace torqued
