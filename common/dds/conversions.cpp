#include "common/dds/conversions.h"

#include <cmath>
#include <limits>

#include "common/error.h"

namespace autodrive::dds {
namespace {

constexpr std::int64_t kNsPerSec = 1'000'000'000;

template <typename M>
M Split(std::int64_t ns, const char* what) {
  std::int64_t sec = ns / kNsPerSec;
  std::int64_t rem = ns % kNsPerSec;
  if (rem < 0) {
    rem += kNsPerSec;
    --sec;
  }
  AUTODRIVE_THROW_UNLESS(
      sec >= std::numeric_limits<std::int32_t>::min() &&
          sec <= std::numeric_limits<std::int32_t>::max(),
      what << " of " << ns << " ns does not fit builtin_interfaces' int32 seconds");
  M m;
  m.sec = static_cast<std::int32_t>(sec);
  m.nanosec = static_cast<std::uint32_t>(rem);
  return m;
}

template <typename M>
std::int64_t Join(const M& m, const char* what) {
  AUTODRIVE_THROW_UNLESS(m.nanosec < kNsPerSec, what << " has nanosec " << m.nanosec
                                                     << ", which must be below 1000000000");
  return std::int64_t{m.sec} * kNsPerSec + std::int64_t{m.nanosec};
}

}  // namespace

msg::Time ToMsg(Time t) { return Split<msg::Time>(t.time_since_epoch().count(), "a time"); }
Time FromMsg(const msg::Time& t) { return Time(Duration(Join(t, "builtin_interfaces/Time"))); }
msg::Duration ToMsg(Duration d) { return Split<msg::Duration>(d.count(), "a duration"); }
Duration FromMsg(const msg::Duration& d) {
  return Duration(Join(d, "builtin_interfaces/Duration"));
}

msg::Pose ToMsg(const RigidTransform3& X_AB) {
  const auto& p = X_AB.translation();
  const auto& q = X_AB.rotation();
  return msg::Pose{{p.x(), p.y(), p.z()}, {q.x(), q.y(), q.z(), q.w()}};
}

RigidTransform3 FromMsg(const msg::Pose& pose) {
  const auto& o = pose.orientation;
  return RigidTransform3({pose.position.x, pose.position.y, pose.position.z},
                         Eigen::Quaterniond(o.w, o.x, o.y, o.z));
}

double YawOf(const msg::Quaternion& q) {
  return std::atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z));
}

std::string_view SignalRequestStatusName(std::uint8_t status) {
  switch (status) {
    case autodrive_msgs_msg_SignalRequestStatus_Constants_RECEIVED:
      return "received";
    case autodrive_msgs_msg_SignalRequestStatus_Constants_PROCESSING:
      return "processing";
    case autodrive_msgs_msg_SignalRequestStatus_Constants_GRANTED:
      return "granted";
    case autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED:
      return "rejected";
    case autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED:
      return "completed";
    case autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED:
      return "cancelled";
    default:
      return "unknown";
  }
}

}  // namespace autodrive::dds
