#pragma once
// The Foxglove WebSocket protocol, server side (subprotocol "foxglove.websocket.v1", JSON message encoding,
// JSON Schema channels): https://github.com/foxglove/ws-protocol/blob/main/docs/spec.md. One channel per
// torque topic; each message is one sample as a JSON object (idl/topic_format.hpp append_json: every field by
// name). The same schemas and payloads go into MCAP recordings (mcap_writer.hpp). Pure functions, no I/O.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "qos.hpp"
#include "sample.hpp"

namespace torqued::dash::foxglove {

inline constexpr const char* kSubprotocol = "foxglove.websocket.v1";

/// Channel id of a topic (1-based, Topic order) and back.
constexpr std::uint32_t channel_id(dds::Topic t) { return static_cast<std::uint32_t>(t) + 1; }
std::optional<dds::Topic> topic_of_channel(std::uint64_t id);

/// "torque.EngineTorque", ... (the IDL type name).
std::string schema_name(dds::Topic t);
/// JSON Schema (draft 2020-12) of a topic's JSON messages: every field with its JSON type and integer bounds.
std::string json_schema(dds::Topic t);
/// The channel's topic name: "/" + DDS topic name ("/torque/EngineTorque").
std::string channel_topic(const dds::DdsSettings& s, dds::Topic t);

/// One sample as a JSON object, no trailing newline.
std::string sample_json(const dds::AnySample& s);

/// Server → client text messages.
std::string server_info(std::string_view name, std::string_view session_id);
std::string advertise(const dds::DdsSettings& s);
std::string status(int level, std::string_view message);

/// Server → client binary "Message Data" (opcode 0x01): subscription id, receive time (ns), payload.
std::string message_data(std::uint32_t subscription_id, std::uint64_t receive_time_ns,
                         std::string_view payload);

/// Client → server: the subscriptions of one client (subscription id → channel id).
struct Subscriptions {
  std::map<std::uint32_t, std::uint32_t> by_id;
  /// Applies one client text message. Returns an error text for the client's status message, or "".
  std::string apply(std::string_view text);
  /// Subscription ids of a channel (a client may subscribe to one channel more than once).
  [[nodiscard]] std::vector<std::uint32_t> of_channel(std::uint32_t channel) const;
};

}  // namespace torqued::dash::foxglove
