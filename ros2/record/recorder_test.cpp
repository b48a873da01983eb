#include "ros2/record/recorder.h"

#include <gtest/gtest.h>

namespace autodrive::ros2 {
namespace {

TEST(RecorderSelected, EverythingButCamerasByDefault) {
  const RecordOptions all;
  EXPECT_TRUE(Selected(all, "/autodrive/scm/spat", "autodrive_msgs/msg/Spat"));
  EXPECT_FALSE(Selected(all, "/autodrive/nigel_1/front_camera", "sensor_msgs/msg/Image"));
  RecordOptions cameras;
  cameras.cameras = true;
  EXPECT_TRUE(Selected(cameras, "/autodrive/nigel_1/front_camera", "sensor_msgs/msg/Image"));
}

TEST(RecorderSelected, TopicsAndExcludeGlobs) {
  RecordOptions o;
  o.topics = {"/autodrive/scm/*", "/autodrive/nigel_1/front_camera"};
  o.exclude = {"/autodrive/scm/dev*"};
  EXPECT_TRUE(Selected(o, "/autodrive/scm/spat", "autodrive_msgs/msg/Spat"));
  EXPECT_FALSE(Selected(o, "/autodrive/scm/devices", "autodrive_msgs/msg/DeviceStatus"));
  EXPECT_FALSE(Selected(o, "/clock", "rosgraph_msgs/msg/Clock"));
  // A camera named by --topics is recorded without --cameras; others are not.
  EXPECT_TRUE(Selected(o, "/autodrive/nigel_1/front_camera", "sensor_msgs/msg/Image"));
  EXPECT_FALSE(Selected(o, "/autodrive/nigel_1/rear_camera", "sensor_msgs/msg/Image"));
  o.exclude.push_back("/autodrive/nigel_1/*");
  EXPECT_FALSE(Selected(o, "/autodrive/nigel_1/front_camera", "sensor_msgs/msg/Image"));
}

}  // namespace
}  // namespace autodrive::ros2
