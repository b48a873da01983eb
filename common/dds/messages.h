#pragma once
/// @file
/// Every message type of the messaging contract (common/msgs/idl), registered with the DDS
/// layer, and short C++ names for them: `autodrive::msg::LaserScan` is the generated
/// `sensor_msgs_msg_dds__LaserScan_`, DDS type "sensor_msgs::msg::dds_::LaserScan_".
/// A test checks that this list covers every struct in the IDL files.

#include <array>

#include "autodrive_msgs/msg/DeviceCommand.h"
#include "autodrive_msgs/msg/DeviceEntry.h"
#include "autodrive_msgs/msg/DeviceStatus.h"
#include "autodrive_msgs/msg/DeviceTable.h"
#include "autodrive_msgs/msg/Event.h"
#include "autodrive_msgs/msg/FleetState.h"
#include "autodrive_msgs/msg/Heartbeat.h"
#include "autodrive_msgs/msg/IntersectionState.h"
#include "autodrive_msgs/msg/KeyValue.h"
#include "autodrive_msgs/msg/MapApproach.h"
#include "autodrive_msgs/msg/MapConnection.h"
#include "autodrive_msgs/msg/MapData.h"
#include "autodrive_msgs/msg/MapIntersection.h"
#include "autodrive_msgs/msg/MapLane.h"
#include "autodrive_msgs/msg/MapSignalGroup.h"
#include "autodrive_msgs/msg/OperatorReply.h"
#include "autodrive_msgs/msg/OperatorRequest.h"
#include "autodrive_msgs/msg/ProcessEntry.h"
#include "autodrive_msgs/msg/ProcessTable.h"
#include "autodrive_msgs/msg/SignRegistry.h"
#include "autodrive_msgs/msg/SignalGroupState.h"
#include "autodrive_msgs/msg/SignalRequest.h"
#include "autodrive_msgs/msg/SignalRequestStatus.h"
#include "autodrive_msgs/msg/SimFault.h"
#include "autodrive_msgs/msg/Spat.h"
#include "autodrive_msgs/msg/TrackedVehicle.h"
#include "autodrive_msgs/msg/TrafficObject.h"
#include "autodrive_msgs/msg/TrafficObjects.h"
#include "autodrive_msgs/msg/TrafficSign.h"
#include "builtin_interfaces/msg/Duration.h"
#include "builtin_interfaces/msg/Time.h"
#include "geometry_msgs/msg/Point.h"
#include "geometry_msgs/msg/Pose.h"
#include "geometry_msgs/msg/PoseStamped.h"
#include "geometry_msgs/msg/PoseWithCovariance.h"
#include "geometry_msgs/msg/Quaternion.h"
#include "geometry_msgs/msg/Twist.h"
#include "geometry_msgs/msg/TwistWithCovariance.h"
#include "geometry_msgs/msg/Vector3.h"
#include "rmw_dds_common/msg/Gid.h"
#include "rmw_dds_common/msg/NodeEntitiesInfo.h"
#include "rmw_dds_common/msg/ParticipantEntitiesInfo.h"
#include "rmw_dds_common_humble/msg/ParticipantEntitiesInfo.h"
#include "rosgraph_msgs/msg/Clock.h"
#include "sensor_msgs/msg/Image.h"
#include "sensor_msgs/msg/Imu.h"
#include "sensor_msgs/msg/JointState.h"
#include "sensor_msgs/msg/LaserScan.h"
#include "std_msgs/msg/Float32.h"
#include "std_msgs/msg/Header.h"
#include "std_msgs/msg/Int32.h"

#include "common/dds/message.h"

/// X-macro over every generated message type: X(c_type, short_name).
#define AUTODRIVE_DDS_MESSAGE_TYPES(X)                                         \
  X(autodrive_msgs_msg_dds__DeviceCommand_, DeviceCommand)                     \
  X(autodrive_msgs_msg_dds__DeviceEntry_, DeviceEntry)                         \
  X(autodrive_msgs_msg_dds__DeviceStatus_, DeviceStatus)                       \
  X(autodrive_msgs_msg_dds__DeviceTable_, DeviceTable)                         \
  X(autodrive_msgs_msg_dds__Event_, Event)                                     \
  X(autodrive_msgs_msg_dds__FleetState_, FleetState)                           \
  X(autodrive_msgs_msg_dds__Heartbeat_, Heartbeat)                             \
  X(autodrive_msgs_msg_dds__IntersectionState_, IntersectionState)             \
  X(autodrive_msgs_msg_dds__KeyValue_, KeyValue)                               \
  X(autodrive_msgs_msg_dds__MapApproach_, MapApproach)                         \
  X(autodrive_msgs_msg_dds__MapConnection_, MapConnection)                     \
  X(autodrive_msgs_msg_dds__MapData_, MapData)                                 \
  X(autodrive_msgs_msg_dds__MapIntersection_, MapIntersection)                 \
  X(autodrive_msgs_msg_dds__MapLane_, MapLane)                                 \
  X(autodrive_msgs_msg_dds__MapSignalGroup_, MapSignalGroup)                   \
  X(autodrive_msgs_msg_dds__OperatorReply_, OperatorReply)                     \
  X(autodrive_msgs_msg_dds__OperatorRequest_, OperatorRequest)                 \
  X(autodrive_msgs_msg_dds__ProcessEntry_, ProcessEntry)                       \
  X(autodrive_msgs_msg_dds__ProcessTable_, ProcessTable)                       \
  X(autodrive_msgs_msg_dds__SignRegistry_, SignRegistry)                       \
  X(autodrive_msgs_msg_dds__SignalGroupState_, SignalGroupState)               \
  X(autodrive_msgs_msg_dds__SignalRequest_, SignalRequest)                     \
  X(autodrive_msgs_msg_dds__SignalRequestStatus_, SignalRequestStatus)         \
  X(autodrive_msgs_msg_dds__SimFault_, SimFault)                               \
  X(autodrive_msgs_msg_dds__Spat_, Spat)                                       \
  X(autodrive_msgs_msg_dds__TrackedVehicle_, TrackedVehicle)                   \
  X(autodrive_msgs_msg_dds__TrafficObject_, TrafficObject)                     \
  X(autodrive_msgs_msg_dds__TrafficObjects_, TrafficObjects)                   \
  X(autodrive_msgs_msg_dds__TrafficSign_, TrafficSign)                         \
  X(builtin_interfaces_msg_dds__Duration_, Duration)                           \
  X(builtin_interfaces_msg_dds__Time_, Time)                                   \
  X(geometry_msgs_msg_dds__Point_, Point)                                      \
  X(geometry_msgs_msg_dds__Pose_, Pose)                                        \
  X(geometry_msgs_msg_dds__PoseStamped_, PoseStamped)                          \
  X(geometry_msgs_msg_dds__PoseWithCovariance_, PoseWithCovariance)            \
  X(geometry_msgs_msg_dds__Quaternion_, Quaternion)                            \
  X(geometry_msgs_msg_dds__Twist_, Twist)                                      \
  X(geometry_msgs_msg_dds__TwistWithCovariance_, TwistWithCovariance)          \
  X(geometry_msgs_msg_dds__Vector3_, Vector3)                                  \
  X(rmw_dds_common_msg_dds__Gid_, Gid)                                         \
  X(rmw_dds_common_msg_dds__NodeEntitiesInfo_, NodeEntitiesInfo)               \
  X(rmw_dds_common_msg_dds__ParticipantEntitiesInfo_, ParticipantEntitiesInfo) \
  X(rosgraph_msgs_msg_dds__Clock_, Clock)                                      \
  X(sensor_msgs_msg_dds__Image_, Image)                                        \
  X(sensor_msgs_msg_dds__Imu_, Imu)                                            \
  X(sensor_msgs_msg_dds__JointState_, JointState)                              \
  X(sensor_msgs_msg_dds__LaserScan_, LaserScan)                                \
  X(std_msgs_msg_dds__Float32_, Float32)                                       \
  X(std_msgs_msg_dds__Header_, Header)                                         \
  X(std_msgs_msg_dds__Int32_, Int32)

#define AUTODRIVE_DDS_REGISTER_(c_type, name) AUTODRIVE_DDS_MESSAGE(c_type)
AUTODRIVE_DDS_MESSAGE_TYPES(AUTODRIVE_DDS_REGISTER_)
#undef AUTODRIVE_DDS_REGISTER_

// Humble's ros_discovery_info type: the same DDS type name as Jazzy's, with a 24-byte Gid
// (common/msgs/idl_humble; its C names are rmw_dds_common_humble_...). Outside the list above:
// it has no IDL in common/msgs/idl and no type hash (Humble has none).
AUTODRIVE_DDS_MESSAGE(rmw_dds_common_humble_msg_dds__ParticipantEntitiesInfo_)

namespace autodrive::msg {
#define AUTODRIVE_DDS_ALIAS_(c_type, name) using name = c_type;
AUTODRIVE_DDS_MESSAGE_TYPES(AUTODRIVE_DDS_ALIAS_)
#undef AUTODRIVE_DDS_ALIAS_
namespace humble {
using ParticipantEntitiesInfo = rmw_dds_common_humble_msg_dds__ParticipantEntitiesInfo_;
using NodeEntitiesInfo = rmw_dds_common_humble_msg_dds__NodeEntitiesInfo_;
using Gid = rmw_dds_common_humble_msg_dds__Gid_;
}  // namespace humble
}  // namespace autodrive::msg

namespace autodrive::dds {
/// The topic descriptor of every registered message type.
inline const auto& AllMessageDescriptors() {
#define AUTODRIVE_DDS_DESC_(c_type, name) &c_type##_desc,
  static const std::array kAll{AUTODRIVE_DDS_MESSAGE_TYPES(AUTODRIVE_DDS_DESC_)};
#undef AUTODRIVE_DDS_DESC_
  return kAll;
}
}  // namespace autodrive::dds
