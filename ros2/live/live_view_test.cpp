#include "ros2/live/live_view.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "ros2/record/ros2msg_schema.h"

#include "common/dds/messages.h"
#include "common/dds/qos.h"
#include "common/dds/writer.h"

namespace autodrive::ros2::live {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

/// A client that keeps what it is sent.
class FakeConnection final : public Connection {
 public:
  explicit FakeConnection(std::uint64_t id) : id_(id) {}
  void Send(OutFrame frame) override {
    std::lock_guard lock(mutex_);
    frames_.push_back(std::move(frame));
  }
  [[nodiscard]] ConnectionStats stats() const override { return {}; }
  [[nodiscard]] std::uint64_t id() const override { return id_; }
  [[nodiscard]] const std::string& remote() const override { return remote_; }
  [[nodiscard]] const std::string& subprotocol() const override { return protocol_; }

  /// The text messages with `op`, parsed.
  std::vector<json> Texts(const std::string& op) const {
    std::lock_guard lock(mutex_);
    std::vector<json> out;
    for (const auto& f : frames_) {
      if (f.binary) continue;
      json j = json::parse(f.text);
      if (j["op"] == op) out.push_back(j);
    }
    return out;
  }
  /// The messageData frames, decoded.
  std::vector<MessageData> Data() const {
    std::lock_guard lock(mutex_);
    std::vector<MessageData> out;
    for (const auto& f : frames_) {
      if (!f.binary) continue;
      std::vector<std::byte> bytes(f.header.begin(), f.header.end());
      bytes.insert(bytes.end(), f.payload->begin(), f.payload->end());
      out.push_back(*DecodeMessageData(bytes));
    }
    return out;
  }

 private:
  std::uint64_t id_;
  std::string remote_ = "test:1";
  std::string protocol_ = "foxglove.websocket.v1";
  mutable std::mutex mutex_;
  std::vector<OutFrame> frames_;
};

std::string Unique(const std::string& what) {
  return "live_view_test_" + std::to_string(::getpid()) + "_" + what;
}

// Calls `step` until `done` holds or 30 s pass; returns `done()`.
bool Until(
    const std::function<bool()>& done, const std::function<void()>& step = [] {}) {
  const auto end = std::chrono::steady_clock::now() + 30s;
  while (!done() && std::chrono::steady_clock::now() < end) {
    step();
    std::this_thread::sleep_for(5ms);
  }
  return done();
}

std::string Subscribe(std::uint32_t id, std::uint32_t channel) {
  return json{{"op", "subscribe"}, {"subscriptions", {{{"id", id}, {"channelId", channel}}}}}
      .dump();
}

/// A live view and a writer of another participant in a partition of their own.
class LiveViewTest : public ::testing::Test {
 protected:
  using IntWriter = dds::Writer<msg::Int32>;

  std::unique_ptr<IntWriter> MakeWriter(const dds::Qos& qos) {
    return std::make_unique<IntWriter>(city_, "rt" + ros_name_, qos);
  }
  /// The topic's channel id; 0 while it is not advertised.
  std::uint32_t channel_of() const {
    for (const Channel& c : view_.channels()) {
      if (c.topic == ros_name_) return c.id;
    }
    return 0;
  }
  /// Discovers until the topic is advertised (`advertised`) or is not.
  bool DiscoverUntil(bool advertised) {
    return Until([&] { return (channel_of() != 0) == advertised; }, [&] { view_.Discover(); });
  }

  const std::string partition_ =
      Unique(::testing::UnitTest::GetInstance()->current_test_info()->name());
  dds::Participant mine_{dds::ParticipantOptions{{}, partition_, {}}};
  dds::Participant city_{dds::ParticipantOptions{{}, partition_, {}}};
  LiveView view_{mine_, {}};
  const std::string ros_name_ = "/autodrive/" + partition_;
};

TEST_F(LiveViewTest, AdvertisesForwardsTheBytesAndReadsOnlyWhileSubscribed) {
  LiveView& view = view_;
  const std::string& ros_name = ros_name_;
  auto writer = MakeWriter(dds::Qos::Stream(10));
  ASSERT_TRUE(DiscoverUntil(true));
  const std::uint32_t channel = channel_of();

  auto a = std::make_shared<FakeConnection>(1);
  auto b = std::make_shared<FakeConnection>(2);
  view.OnOpen(a);
  view.OnOpen(b);
  ASSERT_EQ(a->Texts("serverInfo").size(), 1U);
  const auto advertised = a->Texts("advertise");
  ASSERT_EQ(advertised.size(), 1U);
  bool found = false;
  for (const json& c : advertised[0]["channels"]) {
    if (c["topic"] != ros_name) continue;
    found = true;
    EXPECT_EQ(c["schemaName"], "std_msgs/msg/Int32");
    EXPECT_EQ(c["schemaEncoding"], "ros2msg");
    EXPECT_EQ(c["encoding"], "cdr");
    EXPECT_EQ(c["schema"], std::string(Ros2MsgSchema("std_msgs/msg/Int32")));
    EXPECT_NE(c["schema"].get<std::string>().find("int32 data"), std::string::npos);
  }
  EXPECT_TRUE(found);
  EXPECT_EQ(view.readers(), 0U) << "nothing is read before a subscription";

  view.OnText(a, Subscribe(7, channel));
  view.OnText(b, Subscribe(3, channel));
  EXPECT_EQ(view.readers(), 1U) << "one reader per topic, however many subscribers";
  ASSERT_TRUE(writer->WaitForReaders(1, 30s));
  msg::Int32 sample{};
  sample.data = 42;
  writer->Write(sample);
  ASSERT_TRUE(Until([&] { return !a->Data().empty() && !b->Data().empty(); }));
  const MessageData got = a->Data().front();
  EXPECT_EQ(got.subscription_id, 7U);
  EXPECT_EQ(b->Data().front().subscription_id, 3U);
  // The encapsulation header (XCDR1 little-endian) and the int32, as on the wire.
  const std::vector<std::byte> want = {std::byte{0},  std::byte{1}, std::byte{0}, std::byte{0},
                                       std::byte{42}, std::byte{0}, std::byte{0}, std::byte{0}};
  EXPECT_EQ(got.payload, want);

  // Refusals: the id in use, the channel subscribed twice, a channel not advertised.
  view.OnText(a, Subscribe(7, channel));
  view.OnText(a, Subscribe(8, channel));
  view.OnText(a, Subscribe(9, 999999));
  const auto statuses = a->Texts("status");
  ASSERT_EQ(statuses.size(), 3U);
  EXPECT_EQ(statuses[0]["message"], "subscribe: subscription id 7 is in use");
  EXPECT_EQ(statuses[1]["message"],
            "subscribe: channel " + std::to_string(channel) + " is subscribed already");
  EXPECT_EQ(statuses[2]["message"], "subscribe: channel 999999 is not advertised");

  view.OnText(a, R"({"op":"unsubscribe","subscriptionIds":[7]})");
  EXPECT_EQ(view.readers(), 1U) << "b still subscribes";
  const std::size_t a_before = a->Data().size();
  sample.data = 43;
  writer->Write(sample);
  ASSERT_TRUE(Until([&] { return b->Data().size() == 2; }));
  EXPECT_EQ(a->Data().size(), a_before) << "nothing for an unsubscribed client";
  view.OnClose(b);
  EXPECT_EQ(view.readers(), 0U) << "the last subscriber gone, the reader is deleted";

  // The writer goes: unadvertised; it comes back: advertised again under the same id.
  writer.reset();
  ASSERT_TRUE(DiscoverUntil(false));
  const auto gone = a->Texts("unadvertise");
  ASSERT_EQ(gone.size(), 1U);
  EXPECT_EQ(gone[0]["channelIds"], json::array({channel}));
  writer = MakeWriter(dds::Qos::Stream(10));
  ASSERT_TRUE(DiscoverUntil(true));
  EXPECT_EQ(channel_of(), channel);
  EXPECT_EQ(a->Texts("advertise").size(), 2U);
}

TEST_F(LiveViewTest, AnUnadvertisedTopicEndsItsSubscriptionsAndItsReader) {
  LiveView& view = view_;
  auto writer = MakeWriter(dds::Qos::LatchedState());
  ASSERT_TRUE(DiscoverUntil(true));
  const std::uint32_t channel = channel_of();
  auto a = std::make_shared<FakeConnection>(1);
  view.OnOpen(a);
  view.OnText(a, Subscribe(1, channel));
  EXPECT_EQ(view.readers(), 1U);
  writer.reset();
  ASSERT_TRUE(DiscoverUntil(false));
  EXPECT_EQ(view.readers(), 0U);
  EXPECT_EQ(view.clients().front().subscriptions, 0U);
  // Its subscription id is free again.
  writer = MakeWriter(dds::Qos::LatchedState());
  ASSERT_TRUE(DiscoverUntil(true));
  view.OnText(a, Subscribe(1, channel));
  EXPECT_TRUE(a->Texts("status").empty());
  EXPECT_EQ(view.readers(), 1U);
}

}  // namespace
}  // namespace autodrive::ros2::live
