#include "foxglove.hpp"

#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <type_traits>

#include "topic_format.hpp"

namespace torqued::dash::foxglove {
namespace {

/// JSON Schema "properties" entries from the field visitor of topic_format.hpp.
struct SchemaVisitor {
  nlohmann::json& props;
  template <class V>
  static nlohmann::json type_of() {
    if constexpr (std::is_same_v<V, bool>) {
      return {{"type", "boolean"}};
    } else if constexpr (std::is_integral_v<V>) {
      return {{"type", "integer"},
              {"minimum", std::numeric_limits<V>::min()},
              {"maximum", std::numeric_limits<V>::max()}};
    } else {
      return {{"type", {"number", "null"}}};  // non-finite doubles are written as null
    }
  }
  template <class V>
  void operator()(const char* name, const V&) {
    props[name] = type_of<V>();
  }
  template <class V>
  void operator()(const char* name, const V* /*array*/, int n) {
    props[name] = {{"type", "array"}, {"items", type_of<V>()}, {"minItems", n}, {"maxItems", n}};
  }
};

template <class T>
nlohmann::json schema_of() {
  nlohmann::json props = nlohmann::json::object();
  props["topic"] = {{"type", "string"}, {"const", std::string(dds::TopicTraits<T>::name)}};
  dds::visit_fields(T{}, SchemaVisitor{props});
  nlohmann::json required = nlohmann::json::array();
  for (const auto& [k, v] : props.items()) required.push_back(k);
  return {
      {"$schema", "https://json-schema.org/draft/2020-12/schema"},
      {"title", "torque." + std::string(dds::TopicTraits<T>::name)},
      {"description", "torqued DDS topic " + std::string(dds::TopicTraits<T>::name) + " (idl/torque.idl)"},
      {"type", "object"},
      {"properties", props},
      {"required", required}};
}

template <class F>
decltype(auto) with_type(dds::Topic t, F&& f) {
  switch (t) {
    case dds::Topic::kEngineTorque:
      return f(torque_EngineTorque{});
    case dds::Topic::kEstimatorTorque:
      return f(torque_EstimatorTorque{});
    case dds::Topic::kCylinderTorque:
      return f(torque_CylinderTorque{});
    case dds::Topic::kCrankState:
      return f(torque_CrankState{});
    case dds::Topic::kDaemonStatus:
      break;
  }
  return f(torque_DaemonStatus{});
}

}  // namespace

std::optional<dds::Topic> topic_of_channel(std::uint64_t id) {
  if (id < 1 || id > static_cast<std::uint64_t>(dds::kTopicCount)) return std::nullopt;
  return static_cast<dds::Topic>(id - 1);
}

std::string schema_name(dds::Topic t) {
  return "torque." + std::string(dds::kTopicNames[static_cast<int>(t)]);
}

std::string json_schema(dds::Topic t) {
  return with_type(t, [](auto v) { return schema_of<decltype(v)>().dump(); });
}

std::string channel_topic(const dds::DdsSettings& s, dds::Topic t) { return "/" + s.topic_name(t); }

std::string sample_json(const dds::AnySample& s) {
  std::string out;
  s.visit([&](const auto& v) { dds::append_json(out, v); });
  if (!out.empty() && out.back() == '\n') out.pop_back();
  return out;
}

std::string server_info(std::string_view name, std::string_view session_id) {
  return nlohmann::json{{"op", "serverInfo"},
                        {"name", name},
                        {"capabilities", nlohmann::json::array()},
                        {"supportedEncodings", {"json"}},
                        {"metadata", nlohmann::json::object()},
                        {"sessionId", session_id}}
      .dump();
}

std::string advertise(const dds::DdsSettings& s) {
  nlohmann::json channels = nlohmann::json::array();
  for (int i = 0; i < dds::kTopicCount; ++i) {
    const auto t = static_cast<dds::Topic>(i);
    channels.push_back({{"id", channel_id(t)},
                        {"topic", channel_topic(s, t)},
                        {"encoding", "json"},
                        {"schemaName", schema_name(t)},
                        {"schema", json_schema(t)},
                        {"schemaEncoding", "jsonschema"}});
  }
  return nlohmann::json{{"op", "advertise"}, {"channels", channels}}.dump();
}

std::string status(int level, std::string_view message) {
  return nlohmann::json{{"op", "status"}, {"level", level}, {"message", message}}.dump();
}

std::string message_data(std::uint32_t subscription_id, std::uint64_t receive_time_ns,
                         std::string_view payload) {
  std::string out(1 + 4 + 8, '\0');
  out[0] = 0x01;
  for (int i = 0; i < 4; ++i)
    out[static_cast<std::size_t>(1 + i)] = static_cast<char>(subscription_id >> (8 * i));
  for (int i = 0; i < 8; ++i)
    out[static_cast<std::size_t>(5 + i)] = static_cast<char>(receive_time_ns >> (8 * i));
  out.append(payload);
  return out;
}

std::string Subscriptions::apply(std::string_view text) {
  const nlohmann::json m = nlohmann::json::parse(text, nullptr, false);
  if (m.is_discarded() || !m.is_object() || !m.contains("op") || !m["op"].is_string())
    return "expected a JSON object with an \"op\" string";
  const std::string op = m["op"];
  if (op == "subscribe") {
    if (!m.contains("subscriptions") || !m["subscriptions"].is_array())
      return "subscribe: no subscriptions array";
    for (const auto& s : m["subscriptions"]) {
      if (!s.is_object() || !s.contains("id") || !s.contains("channelId") || !s["id"].is_number_unsigned() ||
          !s["channelId"].is_number_unsigned())
        return "subscribe: each subscription needs unsigned \"id\" and \"channelId\"";
      const auto ch = s["channelId"].get<std::uint64_t>();
      if (!topic_of_channel(ch)) return "subscribe: unknown channel " + std::to_string(ch);
      by_id[s["id"].get<std::uint32_t>()] = static_cast<std::uint32_t>(ch);
    }
    return "";
  }
  if (op == "unsubscribe") {
    if (!m.contains("subscriptionIds") || !m["subscriptionIds"].is_array())
      return "unsubscribe: no subscriptionIds array";
    for (const auto& id : m["subscriptionIds"])
      if (id.is_number_unsigned()) by_id.erase(id.get<std::uint32_t>());
    return "";
  }
  return "unsupported op \"" + op + "\" (this server advertises no capabilities)";
}

std::vector<std::uint32_t> Subscriptions::of_channel(std::uint32_t channel) const {
  std::vector<std::uint32_t> out;
  for (const auto& [id, ch] : by_id)
    if (ch == channel) out.push_back(id);
  return out;
}

}  // namespace torqued::dash::foxglove
