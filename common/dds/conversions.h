#pragma once
/// @file
/// Conversions between kernel types and message fields.

#include <cstdint>
#include <string_view>

#include "common/dds/messages.h"
#include "common/geometry.h"
#include "common/time.h"

namespace autodrive::dds {

/// `t` as builtin_interfaces/Time (sec, nanosec in [0, 1e9)), flooring towards the past for
/// times before the epoch as ROS 2 does. Throws `InputError` when the seconds do not fit int32.
[[nodiscard]] msg::Time ToMsg(Time t);
/// The instant a builtin_interfaces/Time names. Throws `InputError` when nanosec >= 1e9.
[[nodiscard]] Time FromMsg(const msg::Time& t);
/// `d` as builtin_interfaces/Duration; same rules as for Time.
[[nodiscard]] msg::Duration ToMsg(Duration d);
/// The span a builtin_interfaces/Duration names.
[[nodiscard]] Duration FromMsg(const msg::Duration& d);

/// A pose as geometry_msgs/Pose (position in m, orientation as a unit quaternion).
[[nodiscard]] msg::Pose ToMsg(const RigidTransform3& X_AB);
/// The transform a geometry_msgs/Pose describes. Throws `InputError` for non-finite values or
/// a (near-)zero quaternion; other quaternions are normalised.
[[nodiscard]] RigidTransform3 FromMsg(const msg::Pose& pose);
/// The heading (rad, from the map's x, counter-clockwise) of a geometry_msgs/Quaternion: the
/// rotated x axis projected on the plane. Never throws (a zero quaternion gives 0).
[[nodiscard]] double YawOf(const msg::Quaternion& q);

/// The name of a SignalRequestStatus `status` (autodrive_msgs SignalRequestStatus_Constants):
/// "received", "processing", "granted", "rejected", "completed", "cancelled"; "unknown" for
/// any other value.
[[nodiscard]] std::string_view SignalRequestStatusName(std::uint8_t status);

}  // namespace autodrive::dds
