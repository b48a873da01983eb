#pragma once
/// @file
/// A ROS 2 node's readers and writers as rmw_cyclonedds_cpp makes them, on Cyclone's C API
/// alone (none of the project's QoS code): its own participant, a publisher or subscriber in
/// the city's partition (a test city runs in its own; rmw itself sets none), and the QoS of
/// rmw_cyclonedds' `create_readwrite_qos` for each of ROS 2's profiles (ros2/rmw
/// `qos_profiles.h`; shared/research/ros2.md §3):
///   default          keep last 10, reliable, volatile
///   sensor_data      keep last 5,  best effort, volatile
///   system_default   keep last 1,  reliable, volatile (rmw_cyclonedds' reading of it)
///   transient_local  keep last 1,  reliable, transient local (`rclcpp::QoS(1).transient_local()`)
/// each with XCDR1 (rmw_cyclonedds' serdata allows no other) and, for writers, no autodispose.
#include <dds/dds.h>
#include <gtest/gtest.h>

#include <array>
#include <string>
#include <string_view>

namespace autodrive::test {

enum class RosProfile { kDefault, kSensorData, kSystemDefault, kTransientLocal };
inline constexpr std::array kRosProfiles{RosProfile::kDefault, RosProfile::kSensorData,
                                         RosProfile::kSystemDefault, RosProfile::kTransientLocal};

inline std::string_view Name(RosProfile p) {
  switch (p) {
    case RosProfile::kDefault:
      return "default";
    case RosProfile::kSensorData:
      return "sensor_data";
    case RosProfile::kSystemDefault:
      return "system_default";
    case RosProfile::kTransientLocal:
      return "transient_local";
  }
  return "?";
}

/// The QoS rmw_cyclonedds gives a reader or writer of `profile`. Delete with dds_delete_qos.
inline dds_qos_t* RosQos(RosProfile profile, bool writer) {
  dds_qos_t* q = dds_create_qos();
  const bool reliable = profile != RosProfile::kSensorData;
  dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       DDS_INFINITY);
  const int depth = profile == RosProfile::kDefault      ? 10
                    : profile == RosProfile::kSensorData ? 5
                                                         : 1;
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, depth);
  if (profile == RosProfile::kTransientLocal) {
    dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
    dds_qset_durability_service(q, 0, DDS_HISTORY_KEEP_LAST, 1, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  } else {
    dds_qset_durability(q, DDS_DURABILITY_VOLATILE);
  }
  dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(q, 1, &xcdr1);
  if (writer) dds_qset_writer_data_lifecycle(q, false);
  return q;
}

/// A ROS 2 node: one participant of its own, a publisher and a subscriber in `partition`.
class RosNodeLike {
 public:
  /// On DDS domain `domain` (default: the process's default one, as ROS_DOMAIN_ID gives it).
  explicit RosNodeLike(const std::string& partition, dds_domainid_t domain = DDS_DOMAIN_DEFAULT) {
    participant_ = dds_create_participant(domain, nullptr, nullptr);
    EXPECT_GT(participant_, 0);
    dds_qos_t* q = dds_create_qos();
    dds_qset_partition1(q, partition.c_str());
    publisher_ = dds_create_publisher(participant_, q, nullptr);
    subscriber_ = dds_create_subscriber(participant_, q, nullptr);
    dds_delete_qos(q);
  }
  RosNodeLike(const RosNodeLike&) = delete;
  RosNodeLike& operator=(const RosNodeLike&) = delete;
  ~RosNodeLike() { dds_delete(participant_); }

  /// A publisher (`writer`) or subscription of `profile` on DDS topic `topic`. `alone`: it
  /// ignores this node's other readers and writers (not rmw's doing: so that a test that makes
  /// several of one topic sees only how each meets the city's).
  dds_entity_t Endpoint(const dds_topic_descriptor_t* descriptor, const std::string& topic,
                        RosProfile profile, bool writer, bool alone = false) {
    const dds_entity_t t =
        dds_create_topic(participant_, descriptor, topic.c_str(), nullptr, nullptr);
    EXPECT_GT(t, 0) << topic;
    dds_qos_t* q = RosQos(profile, writer);
    if (alone) dds_qset_ignorelocal(q, DDS_IGNORELOCAL_PARTICIPANT);
    const dds_entity_t e = writer ? dds_create_writer(publisher_, t, q, nullptr)
                                  : dds_create_reader(subscriber_, t, q, nullptr);
    dds_delete_qos(q);
    EXPECT_GT(e, 0) << topic;
    return e;
  }

 private:
  dds_entity_t participant_ = 0;
  dds_entity_t publisher_ = 0;
  dds_entity_t subscriber_ = 0;
};

}  // namespace autodrive::test
