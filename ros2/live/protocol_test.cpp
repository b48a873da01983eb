#include "ros2/live/protocol.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

namespace autodrive::ros2::live {
namespace {

using nlohmann::json;

TEST(ChooseSubprotocol, AnswersTheFirstSupportedOneTheClientOffers) {
  EXPECT_EQ(ChooseSubprotocol({"foxglove.websocket.v1"}), "foxglove.websocket.v1");
  EXPECT_EQ(ChooseSubprotocol({"foxglove.sdk.v1"}), "foxglove.sdk.v1");
  // Lichtblick's offer: both, v1 first.
  EXPECT_EQ(ChooseSubprotocol({"foxglove.websocket.v1, foxglove.sdk.v1"}), "foxglove.websocket.v1");
  EXPECT_EQ(ChooseSubprotocol({"chat, foxglove.sdk.v1 ,foxglove.websocket.v1"}), "foxglove.sdk.v1");
  // Several header lines.
  EXPECT_EQ(ChooseSubprotocol({"chat", "foxglove.sdk.v1"}), "foxglove.sdk.v1");
}

TEST(ChooseSubprotocol, RefusesAnOfferOfNeither) {
  EXPECT_EQ(ChooseSubprotocol({}), std::nullopt);
  EXPECT_EQ(ChooseSubprotocol({""}), std::nullopt);
  EXPECT_EQ(ChooseSubprotocol({"chat, foxglove.websocket.v2"}), std::nullopt);
  EXPECT_EQ(ChooseSubprotocol({"foxglove.websocket.v1x"}), std::nullopt);
}

TEST(ServerMessages, ServerInfoAnnouncesNoCapability) {
  const json info = json::parse(ServerInfoJson("autodrive-live", {{"ROS_DISTRO", "jazzy"}}, "7"));
  EXPECT_EQ(info["op"], "serverInfo");
  EXPECT_EQ(info["name"], "autodrive-live");
  EXPECT_EQ(info["capabilities"], json::array());
  EXPECT_FALSE(info.contains("supportedEncodings"));
  EXPECT_EQ(info["metadata"]["ROS_DISTRO"], "jazzy");
  EXPECT_EQ(info["sessionId"], "7");
}

TEST(ServerMessages, AdvertiseCarriesEveryFieldOfEachChannel) {
  Channel c;
  c.id = 3;
  c.topic = "/autodrive/scm/spat";
  c.schema_name = "autodrive_msgs/msg/Spat";
  c.schema = "std_msgs/Header header\n\"quoted\"\n";
  const json a = json::parse(AdvertiseJson({c}));
  EXPECT_EQ(a["op"], "advertise");
  ASSERT_EQ(a["channels"].size(), 1U);
  const json& ch = a["channels"][0];
  EXPECT_EQ(ch["id"], 3);
  EXPECT_EQ(ch["topic"], "/autodrive/scm/spat");
  EXPECT_EQ(ch["encoding"], "cdr");
  EXPECT_EQ(ch["schemaName"], "autodrive_msgs/msg/Spat");
  EXPECT_EQ(ch["schemaEncoding"], "ros2msg");
  EXPECT_EQ(ch["schema"], c.schema);
  // At least one advertise is sent on connect, even with no channel.
  EXPECT_EQ(json::parse(AdvertiseJson({}))["channels"], json::array());
}

TEST(ServerMessages, UnadvertiseAndStatus) {
  const json u = json::parse(UnadvertiseJson({1, 5}));
  EXPECT_EQ(u["op"], "unadvertise");
  EXPECT_EQ(u["channelIds"], json::array({1, 5}));
  const json s = json::parse(StatusJson(StatusLevel::kWarning, "unknown op 'x'"));
  EXPECT_EQ(s["op"], "status");
  EXPECT_EQ(s["level"], 1);
  EXPECT_EQ(s["message"], "unknown op 'x'");
}

TEST(MessageData, HeaderIsOpcodeSubscriptionAndTimestampLittleEndian) {
  const MessageDataHeader h = EncodeMessageDataHeader(0x01020304U, 0x1122334455667788ULL);
  const std::uint8_t want[13] = {0x01, 0x04, 0x03, 0x02, 0x01, 0x88, 0x77,
                                 0x66, 0x55, 0x44, 0x33, 0x22, 0x11};
  for (std::size_t i = 0; i < 13; ++i) EXPECT_EQ(std::to_integer<std::uint8_t>(h[i]), want[i]) << i;
}

TEST(MessageData, DecodesWhatItEncodes) {
  const MessageDataHeader h = EncodeMessageDataHeader(42, 1'700'000'000'123'456'789ULL);
  std::vector<std::byte> frame(h.begin(), h.end());
  const std::vector<std::byte> payload = {std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0},
                                          std::byte{0xab}};
  frame.insert(frame.end(), payload.begin(), payload.end());
  const auto m = DecodeMessageData(frame);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->subscription_id, 42U);
  EXPECT_EQ(m->timestamp_ns, 1'700'000'000'123'456'789ULL);
  EXPECT_EQ(m->payload, payload);
  EXPECT_FALSE(DecodeMessageData(std::span(frame).first(12)).has_value());
  frame[0] = std::byte{0x02};
  EXPECT_FALSE(DecodeMessageData(frame).has_value());
}

TEST(ClientMessages, SubscribeAndUnsubscribe) {
  const auto s = ParseClientText(
      R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":3},{"id":1,"channelId":5}]})");
  ASSERT_TRUE(std::holds_alternative<Subscribe>(s));
  const auto& subs = std::get<Subscribe>(s).subscriptions;
  ASSERT_EQ(subs.size(), 2U);
  EXPECT_EQ(subs[0], std::make_pair(0U, 3U));
  EXPECT_EQ(subs[1], std::make_pair(1U, 5U));
  const auto u = ParseClientText(R"({"op":"unsubscribe","subscriptionIds":[0, 4294967295]})");
  ASSERT_TRUE(std::holds_alternative<Unsubscribe>(u));
  EXPECT_EQ(std::get<Unsubscribe>(u).subscription_ids,
            (std::vector<std::uint32_t>{0, 4294967295U}));
}

TEST(ClientMessages, MalformedSaysWhy) {
  const auto why = [](std::string_view text) {
    const auto m = ParseClientText(text);
    return std::holds_alternative<Malformed>(m) ? std::get<Malformed>(m).why : "(not malformed)";
  };
  EXPECT_EQ(why("{not json"), "not JSON");
  EXPECT_EQ(why("[1,2]"), "not a JSON object");
  EXPECT_EQ(why(R"({"op":3})"), "no string 'op'");
  EXPECT_EQ(why(R"({"subscriptions":[]})"), "no string 'op'");
  EXPECT_EQ(why(R"({"op":"subscribe"})"), "subscribe: 'subscriptions' must be an array");
  EXPECT_EQ(
      why(R"({"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]})"),
      R"(subscribe: each subscription needs 'id' and 'channelId' (uint32), got {"channelId":1,"id":-1})");
  EXPECT_EQ(
      why(R"({"op":"subscribe","subscriptions":[{"id":4294967296,"channelId":1}]})"),
      R"(subscribe: each subscription needs 'id' and 'channelId' (uint32), got {"channelId":1,"id":4294967296})");
  EXPECT_EQ(
      why(R"({"op":"subscribe","subscriptions":[{"id":1.5,"channelId":1}]})"),
      R"(subscribe: each subscription needs 'id' and 'channelId' (uint32), got {"channelId":1,"id":1.5})");
  EXPECT_EQ(why(R"({"op":"unsubscribe","subscriptionIds":["a"]})"),
            R"(unsubscribe: subscription ids are uint32, got "a")");
  EXPECT_EQ(why(R"({"op":"unsubscribe"})"), "unsubscribe: 'subscriptionIds' must be an array");
}

TEST(ClientMessages, PublishingAndOtherCapabilitiesAreUnsupported) {
  for (const char* op : {"advertise", "unadvertise", "getParameters", "setParameters",
                         "subscribeParameterUpdates", "unsubscribeParameterUpdates",
                         "subscribeConnectionGraph", "unsubscribeConnectionGraph", "fetchAsset"}) {
    const auto m = ParseClientText(std::string(R"({"op":")") + op + R"("})");
    ASSERT_TRUE(std::holds_alternative<Unsupported>(m)) << op;
    EXPECT_EQ(std::get<Unsupported>(m).op, op);
  }
  const auto unknown = ParseClientText(R"({"op":"teleport"})");
  ASSERT_TRUE(std::holds_alternative<UnknownOp>(unknown));
  EXPECT_EQ(std::get<UnknownOp>(unknown).op, "teleport");
}

TEST(ClientMessages, BinaryMessagesAreRefused) {
  const std::vector<std::byte> publish = {std::byte{0x01}, std::byte{1}, std::byte{0},
                                          std::byte{0},    std::byte{0}, std::byte{7}};
  const auto p = ParseClientBinary(publish);
  ASSERT_TRUE(std::holds_alternative<Unsupported>(p));
  EXPECT_EQ(std::get<Unsupported>(p).op, "client message data");
  const std::vector<std::byte> call = {std::byte{0x02}};
  EXPECT_EQ(std::get<Unsupported>(ParseClientBinary(call)).op, "service call request");
  const std::vector<std::byte> other = {std::byte{0x7f}};
  EXPECT_EQ(std::get<UnknownOp>(ParseClientBinary(other)).op, "binary opcode 127");
  EXPECT_EQ(std::get<Malformed>(ParseClientBinary({})).why, "empty binary message");
}

}  // namespace
}  // namespace autodrive::ros2::live
