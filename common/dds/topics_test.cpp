#include "common/dds/topics.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <regex>
#include <set>

#include "common/error.h"

namespace autodrive::dds::topics {
namespace {

std::string ErrorOf(std::string_view name) {
  try {
    ValidateRosName(name);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TopicNames, RosNamesGetTheRtPrefixAndBack) {
  EXPECT_EQ(ToDds("/autodrive/nigel_1/lidar"), "rt/autodrive/nigel_1/lidar");
  EXPECT_EQ(ToDds("/clock"), "rt/clock");
  EXPECT_EQ(ToRos("rt/autodrive/scm/spat"), "/autodrive/scm/spat");
}

TEST(TopicNames, InvalidRosNamesAreRejectedWithTheRuleBroken) {
  EXPECT_EQ(ErrorOf("autodrive/x"), "invalid ROS topic name 'autodrive/x': must start with '/'");
  EXPECT_EQ(ErrorOf("/a//b"), "invalid ROS topic name '/a//b': must not contain '//'");
  EXPECT_EQ(ErrorOf("/a/b/"), "invalid ROS topic name '/a/b/': must not end with '/'");
  EXPECT_EQ(ErrorOf("/a/1b"),
            "invalid ROS topic name '/a/1b': a token must not start with a digit");
  EXPECT_EQ(ErrorOf("/a-b"),
            "invalid ROS topic name '/a-b': character '-' is not allowed (only A-Z a-z 0-9 _ /)");
  EXPECT_EQ(ErrorOf("/"), "invalid ROS topic name '/': must have at least one token after '/'");
  EXPECT_EQ(ErrorOf(""), "invalid ROS topic name '': must start with '/'");
  EXPECT_NE(ErrorOf("/" + std::string(247, 'a')), "");
  EXPECT_EQ(ErrorOf("/" + std::string(246, 'a')), "");
}

TEST(TopicNames, ToRosRejectsNamesWithoutTheRtPrefix) {
  try {
    (void)ToRos("autodrive/x");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "DDS topic 'autodrive/x' is not a ROS topic (no 'rt/' prefix)");
  }
  EXPECT_THROW((void)ToRos("rq/autodrive/x"), InputError);
}

TEST(TopicNames, VehicleTopicsAreTheDevkitNames) {
  const VehicleId v(3);
  EXPECT_EQ(Throttle(v).name, "rt/autodrive/nigel_3/throttle");
  EXPECT_EQ(Steering(v).name, "rt/autodrive/nigel_3/steering");
  EXPECT_EQ(LeftEncoder(v).name, "rt/autodrive/nigel_3/left_encoder");
  EXPECT_EQ(RightEncoder(v).name, "rt/autodrive/nigel_3/right_encoder");
  EXPECT_EQ(Ips(v).name, "rt/autodrive/nigel_3/ips");
  EXPECT_EQ(Imu(v).name, "rt/autodrive/nigel_3/imu");
  EXPECT_EQ(Lidar(v).name, "rt/autodrive/nigel_3/lidar");
  EXPECT_EQ(FrontCamera(v).name, "rt/autodrive/nigel_3/front_camera");
  EXPECT_EQ(RearCamera(v).name, "rt/autodrive/nigel_3/rear_camera");
  EXPECT_EQ(ThrottleCommand(v).name, "rt/autodrive/nigel_3/throttle_command");
  EXPECT_EQ(SteeringCommand(v).name, "rt/autodrive/nigel_3/steering_command");
  EXPECT_EQ(HeadlightsCommand(v).name, "rt/autodrive/nigel_3/headlights_command");
  EXPECT_EQ(IndicatorsCommand(v).name, "rt/autodrive/nigel_3/indicators_command");
}

TEST(TopicNames, SignalTopicsAreTheDevkitNamesAndLatched) {
  EXPECT_EQ(SignalCommand(SignalHeadId(2)).name, "rt/autodrive/signal_2/command");
  EXPECT_EQ(SignalState(SignalHeadId(2)).name, "rt/autodrive/signal_2/state");
  EXPECT_EQ(SignalCommand(SignalHeadId(2)).qos, Qos::LatchedState());
}

TEST(TopicNames, EveryCatalogueTopicIsAValidRosTopicWithTheRightTypeAndQos) {
  struct Row {
    std::string name;
    std::string_view type;
    Qos qos;
  };
  const VehicleId v(1);
  std::vector<Row> rows;
  std::set<std::string> names;
  for (const CatalogueEntry& e : Catalogue()) {
    rows.push_back({e.name, e.descriptor->m_typename, e.qos});
    EXPECT_TRUE(names.insert(e.name).second) << e.name << " twice";
  }
  EXPECT_EQ(rows.size(), 41u);
  const std::regex type_re("^[a-z][a-z0-9_]*::msg::dds_::[A-Z][A-Za-z0-9]*_$");
  for (const auto& row : rows) {
    SCOPED_TRACE(row.name);
    EXPECT_TRUE(row.name.starts_with("rt/"));
    EXPECT_NO_THROW((void)ToRos(row.name));
    EXPECT_TRUE(std::regex_match(std::string(row.type), type_re)) << row.type;
    // Everything is reliable (so ROS default subscribers match) except /clock, which follows
    // ROS 2's ClockQoS.
    if (row.name == "rt/clock") {
      EXPECT_EQ(row.qos.reliability, Qos::Reliability::kBestEffort);
      EXPECT_EQ(row.type, "rosgraph_msgs::msg::dds_::Clock_");
    } else {
      EXPECT_EQ(row.qos.reliability, Qos::Reliability::kReliable);
    }
  }
  EXPECT_EQ(Map().qos.durability, Qos::Durability::kTransientLocal);
  EXPECT_EQ(Signs().qos.durability, Qos::Durability::kTransientLocal);
  // A restarted SCM finds each launcher's last table: how its own death is reported to it.
  EXPECT_EQ(Processes().qos.durability, Qos::Durability::kTransientLocal);
  EXPECT_EQ(Spat().qos.durability, Qos::Durability::kVolatile);
  EXPECT_EQ(TypeName<decltype(Lidar(v))::Type>(), "sensor_msgs::msg::dds_::LaserScan_");
  EXPECT_EQ(TypeName<decltype(Spat())::Type>(), "autodrive_msgs::msg::dds_::Spat_");
}

// The lights follow the SCM's heartbeat; with DDS Security only the SCM may write it, so the
// device hosts' heartbeats must be a topic of their own.
TEST(TopicNames, TheScmAndTheDeviceHostsHaveTheirOwnHeartbeatTopics) {
  EXPECT_EQ(Heartbeat().name, "rt/autodrive/scm/heartbeat");
  EXPECT_EQ(InfraHeartbeat().name, "rt/autodrive/infra/heartbeat");
  EXPECT_EQ(InfraHeartbeat().qos, Heartbeat().qos);
  EXPECT_EQ(Heartbeat().qos.ToString(), "reliable/volatile/keep_last(16)");
}

TEST(TopicNames, EachOperatorHasItsOwnRequestTopicAndNamesAreOneToken) {
  EXPECT_EQ(OperatorRequests("alice").name, "rt/autodrive/scm/operator/alice/request");
  EXPECT_EQ(OperatorRequests().name, "rt/autodrive/scm/operator/request");
  EXPECT_EQ(DeviceCommands().name, "rt/autodrive/scm/device_command");
  for (const char* bad : {"", "a/b", "1st", "al ice", "x/../y"}) {
    try {
      (void)OperatorRequests(bad);
      FAIL() << bad;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr("an operator name must be 1 to 64 letters"));
    }
  }
}

TEST(Qos, NonBlockingKeepsTheProfileButNeverWaits) {
  const Qos q = Qos::Command().NonBlocking();
  EXPECT_EQ(q.max_blocking, Duration{0});
  EXPECT_EQ(q.ToString(), Qos::Command().ToString());
  EXPECT_GT(Qos::Command().max_blocking, Duration{0});
}

TEST(Qos, ProfilesPrintAndRejectBadDepths) {
  EXPECT_EQ(Qos::Stream().ToString(), "reliable/volatile/keep_last(1)");
  EXPECT_EQ(Qos::LatchedState(3).ToString(), "reliable/transient_local/keep_last(3)");
  EXPECT_EQ(Qos::Command().ToString(), "reliable/volatile/keep_all");
  EXPECT_EQ(Qos::BestEffortStream().ToString(), "best_effort/volatile/keep_last(5)");
  try {
    (void)Qos::Stream(0);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "Stream QoS depth must be >= 1, got 0");
  }
}

}  // namespace
}  // namespace autodrive::dds::topics
