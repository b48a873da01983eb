// Peers whose QoS cannot match: each reader's and writer's first one is reported once, with the
// policy and what a ROS 2 node should use; a peer in another partition is another city.
#include "common/dds/incompatible_qos.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"

namespace autodrive::dds {
namespace {

using namespace std::chrono_literals;

std::string Unique(const std::string& what) {
  return "incompatible_qos_test_" + std::to_string(::getpid()) + "_" + what;
}

// Collects what a participant's handler is given.
struct Reports {
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<IncompatibleQos> got;
  void Attach(const Participant& p) {
    p.OnIncompatibleQos([this](const IncompatibleQos& q) {
      std::lock_guard lock(mutex);
      got.push_back(q);
      changed.notify_all();
    });
  }
  bool WaitFor(std::size_t n) {
    std::unique_lock lock(mutex);
    return changed.wait_for(lock, 10s, [&] { return got.size() >= n; });
  }
};

TEST(IncompatibleQos, ABestEffortWriterToAReliableReaderIsReportedOnceNamingReliability) {
  const std::string partition = Unique("reliability");
  Participant ours(ParticipantOptions{{}, partition, {}});
  Participant ros(ParticipantOptions{{}, partition, {}});
  Reports reports;
  reports.Attach(ours);
  Reader<msg::OperatorRequest> reader(ours, "rt/autodrive/test/qos_request", Qos::Command());
  // Waiting for writers narrows the reader's status mask: the report must come all the same.
  EXPECT_FALSE(reader.WaitForWriters(1, std::chrono::milliseconds(1)));
  Writer<msg::OperatorRequest> sensor_data(ros, "rt/autodrive/test/qos_request",
                                           Qos::BestEffortStream(5));
  ASSERT_TRUE(reports.WaitFor(1));
  Writer<msg::OperatorRequest> another(ros, "rt/autodrive/test/qos_request",
                                       Qos::BestEffortStream(5));
  // A reliable writer still matches the reader: the reports are done by then.
  Writer<msg::OperatorRequest> good(ros, "rt/autodrive/test/qos_request", Qos::Command());
  ASSERT_TRUE(good.WaitForReaders(1, 10s));
  std::lock_guard lock(reports.mutex);
  ASSERT_EQ(reports.got.size(), 1u) << "only the first incompatible peer of a reader";
  const IncompatibleQos& q = reports.got[0];
  EXPECT_EQ(q.topic, "/autodrive/test/qos_request");
  EXPECT_TRUE(q.our_reader);
  EXPECT_EQ(q.policy, "RELIABILITY");
  EXPECT_EQ(q.advice, "rclcpp::QoS(10) (reliable, not SensorDataQoS)");
  EXPECT_EQ(q.Message(),
            "incompatible QoS on /autodrive/test/qos_request: a writer offers less RELIABILITY "
            "than our reader requests; publish with rclcpp::QoS(10) (reliable, not "
            "SensorDataQoS)");
}

TEST(IncompatibleQos, ABestEffortWriterOfARosInputTopicIsReadNotReported) {
  const std::string partition = Unique("ros_input");
  Participant ours(ParticipantOptions{{}, partition, {}});
  Participant ros(ParticipantOptions{{}, partition, {}});
  Reports reports;
  reports.Attach(ours);
  // The ROS node's SensorDataQoS publishers exist before our readers (a node started first).
  Writer<msg::Point> ips(ros, "rt/autodrive/test/qos_ips", Qos::BestEffortStream(5));
  Writer<msg::Point> plain(ros, "rt/autodrive/test/qos_plain", Qos::BestEffortStream(5));
  Reader<msg::Point> ros_input(ours, "rt/autodrive/test/qos_ips", Qos::RosInput());
  // The control: a plain reliable reader of the same kind of writer is reported.
  Reader<msg::Point> stream(ours, "rt/autodrive/test/qos_plain", Qos::Stream());
  ASSERT_TRUE(reports.WaitFor(1));
  ASSERT_TRUE(ros_input.WaitForWriters(1, 10s));
  ips.Write(msg::Point{1.0, 2.0, 3.0});
  ASSERT_TRUE(ros_input.WaitForData(10s));
  const auto got = ros_input.TakeOne();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ((*got)->y, 2.0);
  std::lock_guard lock(reports.mutex);
  ASSERT_EQ(reports.got.size(), 1u);
  EXPECT_EQ(reports.got[0].topic, "/autodrive/test/qos_plain");
}

TEST(IncompatibleQos, APeerInAnotherPartitionIsAnotherCityNotAMistake) {
  Participant ours(ParticipantOptions{{}, Unique("partition_a"), {}});
  Participant other_city(ParticipantOptions{{}, Unique("partition_b"), {}});
  Participant ros(ParticipantOptions{{}, Unique("partition_a"), {}});
  Reports reports;
  reports.Attach(ours);
  Reader<msg::Spat> reader(ours, "rt/autodrive/test/qos_partition", Qos::Stream());
  Writer<msg::Spat> elsewhere(other_city, "rt/autodrive/test/qos_partition", Qos::Stream());
  // A best-effort writer in our partition afterwards is the reader's first incompatible peer.
  Writer<msg::Spat> sensor_data(ros, "rt/autodrive/test/qos_partition", Qos::BestEffortStream(5));
  ASSERT_TRUE(reports.WaitFor(1));
  Writer<msg::Spat> good(ros, "rt/autodrive/test/qos_partition", Qos::Stream());
  ASSERT_TRUE(good.WaitForReaders(1, 10s));
  std::lock_guard lock(reports.mutex);
  ASSERT_EQ(reports.got.size(), 1u);
  EXPECT_EQ(reports.got[0].policy, "RELIABILITY");
}

TEST(IncompatibleQos, ATransientLocalReaderOfAVolatileStreamIsReportedNamingDurability) {
  const std::string partition = Unique("durability");
  Participant ours(ParticipantOptions{{}, partition, {}});
  Participant ros(ParticipantOptions{{}, partition, {}});
  Reports reports;
  reports.Attach(ours);
  Writer<msg::Spat> writer(ours, "rt/autodrive/test/qos_spat", Qos::Stream());
  Reader<msg::Spat> latched(ros, "rt/autodrive/test/qos_spat", Qos::LatchedState());
  ASSERT_TRUE(reports.WaitFor(1));
  std::lock_guard lock(reports.mutex);
  const IncompatibleQos& q = reports.got[0];
  EXPECT_FALSE(q.our_reader);
  EXPECT_EQ(q.policy, "DURABILITY");
  EXPECT_EQ(q.advice, "rclcpp::QoS(10) or rclcpp::SensorDataQoS() (volatile, not transient_local)");
}

TEST(IncompatibleQos, AdviceNamesTheRclcppQos) {
  EXPECT_EQ(RclcppQosFor(Qos::LatchedState(), /*publisher=*/true),
            "rclcpp::QoS(1).transient_local()");
  EXPECT_EQ(RclcppQosFor(Qos::Stream(), true), "rclcpp::QoS(10) (reliable, not SensorDataQoS)");
  EXPECT_EQ(RclcppQosFor(Qos::BestEffortStream(1), true),
            "rclcpp::QoS(10) or rclcpp::SensorDataQoS()");
  EXPECT_EQ(RclcppQosFor(Qos::BestEffortStream(1), false), "rclcpp::SensorDataQoS() (best effort)");
  EXPECT_EQ(QosPolicyName(DDS_DEADLINE_QOS_POLICY_ID), "DEADLINE");
}

}  // namespace
}  // namespace autodrive::dds
