#include "ros2/record/ros2msg_schema.h"

#include <gtest/gtest.h>

#include <string>

#include "common/dds/raw.h"

namespace autodrive::ros2 {
namespace {

TEST(Ros2MsgSchema, EveryRegisteredTypeHasOne) {
  for (const auto& type : dds::MessageTypes()) {
    EXPECT_FALSE(Ros2MsgSchema(type.ros_type_name).empty()) << type.ros_type_name;
    EXPECT_EQ(Ros2MsgSchema(type.ros_type_name), Ros2MsgSchema(type.dds_type_name));
  }
}

TEST(Ros2MsgSchema, DependenciesFollowOnceAfterTheDelimiter) {
  const std::string header(Ros2MsgSchema("std_msgs/msg/Header"));
  EXPECT_NE(header.find("builtin_interfaces/Time stamp"), std::string::npos);
  const std::string delimiter = "\n" + std::string(80, '=') + "\nMSG: builtin_interfaces/Time\n";
  EXPECT_NE(header.find(delimiter), std::string::npos);

  // Imu names Header, Quaternion and Vector3 (twice): each once, Time only under Header.
  const std::string imu(Ros2MsgSchema("sensor_msgs/msg/Imu"));
  for (const char* dep : {"std_msgs/Header", "builtin_interfaces/Time", "geometry_msgs/Quaternion",
                          "geometry_msgs/Vector3"}) {
    const std::string line = "\nMSG: " + std::string(dep) + "\n";
    const auto first = imu.find(line);
    ASSERT_NE(first, std::string::npos) << dep;
    EXPECT_EQ(imu.find(line, first + 1), std::string::npos) << dep << " twice";
  }
  EXPECT_LT(imu.find("MSG: std_msgs/Header"), imu.find("MSG: geometry_msgs/Quaternion"));
}

TEST(Ros2MsgSchema, UnknownTypeIsEmpty) {
  EXPECT_TRUE(Ros2MsgSchema("std_msgs/msg/NoSuchType").empty());
  EXPECT_TRUE(Ros2MsgSchema("").empty());
}

}  // namespace
}  // namespace autodrive::ros2
