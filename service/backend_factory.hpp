#pragma once
// The ONE place that maps configuration names to io/ backends (docs/conventions.md habit 6):
//   inputs.edges.backend: file (format csv | list) | gpio | can_encoder
//   inputs.can.backend:   file (candump -l) | socketcan
// Sources deliver their own clock's timestamps; the CAN time offset (inputs.can.time_offset_s) is NOT applied
// here: pass can_time_offset_ns(config) to ReplayMerger (or add it where frames are consumed), exactly once.
// Load-time only (allocates, opens files/sockets).
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "can_encoder.hpp"
#include "config.hpp"
#include "dbc.hpp"
#include "signal_store.hpp"
#include "source.hpp"
#include "time_sanity.hpp"

namespace torqued {

/// Channel indices the factory gives edges (EdgeEvent::channel) and that decoder_params() sets.
inline constexpr std::uint8_t kCrankChannel = 0;
inline constexpr std::uint8_t kCamChannel = 1;

/// Edge source for config.inputs.edges (+ wheel channel names). nullptr with `error` set on failure
/// ("inputs.edges: <path>:<line>: ..."). For can_encoder the source owns its own CAN source (a second
/// candump reader of inputs.can.path, or a second SocketCAN socket filtered to encoder_can_id).
[[nodiscard]] std::unique_ptr<EdgeSource> make_edge_source(const Config& config, std::string* error);

/// CAN source for config.inputs.can; nullptr with `error` set on failure. With no CAN path configured for the
/// file backend, returns nullptr and leaves `error` empty (no CAN input).
[[nodiscard]] std::unique_ptr<CanSource> make_can_source(const Config& config, std::string* error);

/// inputs.can.time_offset_s in ns (rounded).
[[nodiscard]] std::int64_t can_time_offset_ns(const Config& config) noexcept;
/// Time sanity of the file sources (inputs.max_time_jump_s, inputs.time_rebase_records).
[[nodiscard]] TimeSanityOptions time_sanity_options(const Config& config) noexcept;

/// Decoder parameters from the config with the factory's channel indices and cam settings filled in.
[[nodiscard]] DecoderParams decoder_params(const Config& config) noexcept;

/// Encoder settings for inputs.edges.backend can_encoder. align_to_receive_time is on only for the live
/// SocketCAN path (edges moved onto the frames' receive clock, like the CAN signals; docs/live.md); a candump
/// replay keeps the encoder's own clock, so replays stay deterministic.
[[nodiscard]] CanEncoderConfig can_encoder_config(const Config& config) noexcept;

/// Parse config.can.dbc (nullopt + error when it fails; nullopt and empty error when no DBC is configured).
/// The parser's warnings ("file:line: ...", e.g. a signal that does not fit its message and is dropped) go to
/// `warnings` when given.
[[nodiscard]] std::optional<DbcDatabase> load_dbc(const Config& config, std::string* error,
                                                  std::vector<std::string>* warnings = nullptr);

/// Bind every mapped quantity of config.can.signals in `store`; false with all problems in `error`.
bool bind_signals(const Config& config, SignalStore& store, std::string* error);

}  // namespace torqued
