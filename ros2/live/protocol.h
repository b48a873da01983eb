#pragma once
/// @file
/// The Foxglove WebSocket protocol (github.com/foxglove/ws-protocol, docs/spec.md), the part a
/// read-only live view speaks: the subprotocol choice, the server's JSON messages (serverInfo,
/// advertise, unadvertise, status), the binary messageData header, and the client's messages
/// read into typed values. Pure functions, no I/O.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

namespace autodrive::ros2::live {

/// The subprotocols this server speaks: the protocol's v1 name and the Foxglove SDK's name for
/// the same protocol (Lichtblick offers both). Which one is answered follows the client's order.
inline constexpr std::array<std::string_view, 2> kSubprotocols = {"foxglove.websocket.v1",
                                                                  "foxglove.sdk.v1"};

/// The subprotocol to answer a WebSocket upgrade whose `Sec-WebSocket-Protocol` header values
/// are `offered` (each a comma-separated list): the first the client lists that is one of
/// `kSubprotocols`; nullopt when it offers none of them.
[[nodiscard]] std::optional<std::string> ChooseSubprotocol(
    const std::vector<std::string_view>& offered);

/// A channel the server advertises: one topic with its type.
struct Channel {
  std::uint32_t id = 0;
  std::string topic;             ///< ROS name ("/autodrive/scm/spat")
  std::string encoding = "cdr";  ///< message encoding
  std::string schema_name;       ///< "pkg/msg/Type"
  std::string schema;            ///< the ros2msg text
  std::string schema_encoding = "ros2msg";

  bool operator==(const Channel&) const = default;
};

/// Status levels of the `status` message.
enum class StatusLevel : std::uint8_t { kInfo = 0, kWarning = 1, kError = 2 };

/// The serverInfo message: `name`, no capabilities (nothing a client may publish, call or set),
/// `metadata` key/value pairs and `session_id`.
[[nodiscard]] std::string ServerInfoJson(
    std::string_view name, const std::vector<std::pair<std::string, std::string>>& metadata,
    std::string_view session_id);
/// An advertise message for `channels`.
[[nodiscard]] std::string AdvertiseJson(const std::vector<Channel>& channels);
/// An unadvertise message for the channel ids `ids`.
[[nodiscard]] std::string UnadvertiseJson(const std::vector<std::uint32_t>& ids);
/// A status message.
[[nodiscard]] std::string StatusJson(StatusLevel level, std::string_view message);

/// The 13 bytes that open a binary messageData frame: opcode 0x01, the subscription id
/// (uint32) and the timestamp in ns (uint64), little-endian; the payload follows.
using MessageDataHeader = std::array<std::byte, 13>;
[[nodiscard]] MessageDataHeader EncodeMessageDataHeader(std::uint32_t subscription_id,
                                                        std::uint64_t timestamp_ns);

/// A decoded messageData frame (for tests and clients).
struct MessageData {
  std::uint32_t subscription_id = 0;
  std::uint64_t timestamp_ns = 0;
  std::vector<std::byte> payload;
};
/// Reads a binary messageData frame; nullopt when `frame` is not one (other opcode, short).
[[nodiscard]] std::optional<MessageData> DecodeMessageData(std::span<const std::byte> frame);

/// What a client asked for in one text message.
struct Subscribe {
  /// (subscription id, channel id), as the client listed them.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> subscriptions;
};
struct Unsubscribe {
  std::vector<std::uint32_t> subscription_ids;
};
/// An operation this server does not offer (client publishing, parameters, services, the
/// connection graph, assets): answered with a status error naming `op`.
struct Unsupported {
  std::string op;
};
/// An operation the protocol does not know: answered with a status warning.
struct UnknownOp {
  std::string op;
};
/// Not a protocol message (not JSON, not an object, no string `op`, fields of the wrong type):
/// answered with a status error saying `why`.
struct Malformed {
  std::string why;
};
using ClientMessage = std::variant<Subscribe, Unsubscribe, Unsupported, UnknownOp, Malformed>;

/// Reads one client text message. Never throws.
[[nodiscard]] ClientMessage ParseClientText(std::string_view text);
/// Reads one client binary message: this server takes none, so client message data (0x01) and
/// service calls (0x02) are `Unsupported`, another opcode `UnknownOp`, an empty one `Malformed`.
[[nodiscard]] ClientMessage ParseClientBinary(std::span<const std::byte> frame);

}  // namespace autodrive::ros2::live
