#pragma once
// `torqued --check-config` with a recording: measure where the recording's cam edge falls in the
// 720° cycle and warn when the configured cam window does not fit it. Not real-time (reads the file).
#include <cstdint>
#include <string>
#include <vector>

#include "config.hpp"

namespace torqued {

/// Warnings (empty: nothing to say) for the configured wheel.decoder cam window against the edge recording
/// of `config` (inputs.edges file with a cam column; otherwise nothing is checked). Decodes at most
/// `max_edges` edges with cam_window: auto to measure the cam angle a (within a revolution; the cycle has it
/// at a and a + 360). Warns when neither lies in the window (every cam edge would be a cam phase error), when
/// both do (the phase is ambiguous), or when the one inside is within `margin_deg` of a window edge (timing
/// jitter would flip the phase by 360°); and when no angle could be measured.
[[nodiscard]] std::vector<std::string> cam_window_warnings(const Config& config,
                                                           std::int64_t max_edges = 2'000'000,
                                                           double margin_deg = 20.0);

}  // namespace torqued
