#include "ros2/live/protocol.h"

#include <algorithm>
#include <cstring>
#include <limits>

#include <nlohmann/json.hpp>

namespace autodrive::ros2::live {

namespace {

using nlohmann::json;

std::string_view Trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t");
  return s.substr(first, last - first + 1);
}

// A uint32 field of `object`; nullopt when missing or not a non-negative integer that fits.
std::optional<std::uint32_t> Uint32Field(const json& object, const char* key) {
  const auto it = object.find(key);
  if (it == object.end() || !it->is_number_integer()) return std::nullopt;
  if (!it->is_number_unsigned() && it->get<std::int64_t>() < 0) return std::nullopt;
  const auto v = it->get<std::uint64_t>();
  if (v > std::numeric_limits<std::uint32_t>::max()) return std::nullopt;
  return static_cast<std::uint32_t>(v);
}

ClientMessage ParseSubscribe(const json& message) {
  const auto list = message.find("subscriptions");
  if (list == message.end() || !list->is_array()) {
    return Malformed{"subscribe: 'subscriptions' must be an array"};
  }
  Subscribe s;
  for (const json& entry : *list) {
    const auto id = entry.is_object() ? Uint32Field(entry, "id") : std::nullopt;
    const auto channel = entry.is_object() ? Uint32Field(entry, "channelId") : std::nullopt;
    if (!id || !channel) {
      return Malformed{"subscribe: each subscription needs 'id' and 'channelId' (uint32), got " +
                       entry.dump()};
    }
    s.subscriptions.emplace_back(*id, *channel);
  }
  return s;
}

ClientMessage ParseUnsubscribe(const json& message) {
  const auto list = message.find("subscriptionIds");
  if (list == message.end() || !list->is_array()) {
    return Malformed{"unsubscribe: 'subscriptionIds' must be an array"};
  }
  Unsubscribe u;
  for (const json& entry : *list) {
    const json wrapped = {{"id", entry}};
    const auto id = Uint32Field(wrapped, "id");
    if (!id) return Malformed{"unsubscribe: subscription ids are uint32, got " + entry.dump()};
    u.subscription_ids.push_back(*id);
  }
  return u;
}

}  // namespace

std::optional<std::string> ChooseSubprotocol(const std::vector<std::string_view>& offered) {
  for (std::string_view header : offered) {
    while (!header.empty()) {
      const auto comma = header.find(',');
      const std::string_view token = Trim(header.substr(0, comma));
      if (std::find(kSubprotocols.begin(), kSubprotocols.end(), token) != kSubprotocols.end()) {
        return std::string(token);
      }
      if (comma == std::string_view::npos) break;
      header.remove_prefix(comma + 1);
    }
  }
  return std::nullopt;
}

std::string ServerInfoJson(std::string_view name,
                           const std::vector<std::pair<std::string, std::string>>& metadata,
                           std::string_view session_id) {
  json m = json::object();
  for (const auto& [key, value] : metadata) m[key] = value;
  return json{{"op", "serverInfo"},
              {"name", name},
              {"capabilities", json::array()},
              {"metadata", m},
              {"sessionId", session_id}}
      .dump();
}

std::string AdvertiseJson(const std::vector<Channel>& channels) {
  json list = json::array();
  for (const Channel& c : channels) {
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", c.encoding},
                    {"schemaName", c.schema_name},
                    {"schema", c.schema},
                    {"schemaEncoding", c.schema_encoding}});
  }
  return json{{"op", "advertise"}, {"channels", list}}.dump();
}

std::string UnadvertiseJson(const std::vector<std::uint32_t>& ids) {
  return json{{"op", "unadvertise"}, {"channelIds", ids}}.dump();
}

std::string StatusJson(StatusLevel level, std::string_view message) {
  return json{{"op", "status"}, {"level", static_cast<int>(level)}, {"message", message}}.dump();
}

MessageDataHeader EncodeMessageDataHeader(std::uint32_t subscription_id,
                                          std::uint64_t timestamp_ns) {
  MessageDataHeader h{};
  h[0] = std::byte{0x01};
  for (std::size_t i = 0; i < 4; ++i) {
    h[1 + i] = static_cast<std::byte>((subscription_id >> (8 * i)) & 0xffU);
  }
  for (std::size_t i = 0; i < 8; ++i) {
    h[5 + i] = static_cast<std::byte>((timestamp_ns >> (8 * i)) & 0xffU);
  }
  return h;
}

std::optional<MessageData> DecodeMessageData(std::span<const std::byte> frame) {
  if (frame.size() < sizeof(MessageDataHeader) || frame[0] != std::byte{0x01}) {
    return std::nullopt;
  }
  MessageData m;
  for (std::size_t i = 0; i < 4; ++i) {
    m.subscription_id |= std::to_integer<std::uint32_t>(frame[1 + i]) << (8 * i);
  }
  for (std::size_t i = 0; i < 8; ++i) {
    m.timestamp_ns |= std::to_integer<std::uint64_t>(frame[5 + i]) << (8 * i);
  }
  m.payload.assign(frame.begin() + sizeof(MessageDataHeader), frame.end());
  return m;
}

ClientMessage ParseClientText(std::string_view text) {
  const json message = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (message.is_discarded()) return Malformed{"not JSON"};
  if (!message.is_object()) return Malformed{"not a JSON object"};
  const auto op = message.find("op");
  if (op == message.end() || !op->is_string()) return Malformed{"no string 'op'"};
  const auto& name = op->get_ref<const std::string&>();
  if (name == "subscribe") return ParseSubscribe(message);
  if (name == "unsubscribe") return ParseUnsubscribe(message);
  static constexpr std::string_view kUnsupported[] = {"advertise",
                                                      "unadvertise",
                                                      "getParameters",
                                                      "setParameters",
                                                      "subscribeParameterUpdates",
                                                      "unsubscribeParameterUpdates",
                                                      "subscribeConnectionGraph",
                                                      "unsubscribeConnectionGraph",
                                                      "fetchAsset"};
  if (std::find(std::begin(kUnsupported), std::end(kUnsupported), name) != std::end(kUnsupported)) {
    return Unsupported{name};
  }
  return UnknownOp{name};
}

ClientMessage ParseClientBinary(std::span<const std::byte> frame) {
  if (frame.empty()) return Malformed{"empty binary message"};
  switch (std::to_integer<int>(frame[0])) {
    case 0x01:
      return Unsupported{"client message data"};
    case 0x02:
      return Unsupported{"service call request"};
    default:
      return UnknownOp{"binary opcode " + std::to_string(std::to_integer<int>(frame[0]))};
  }
}

}  // namespace autodrive::ros2::live
