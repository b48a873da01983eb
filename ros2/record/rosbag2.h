#pragma once
/// @file
/// What rosbag2 puts beside the messages of an MCAP file: each channel's
/// `offered_qos_profiles` (YAML, rmw enum numbers) and `topic_type_hash` metadata, and the
/// `rosbag2` Metadata record's `serialized_metadata` (the bag's metadata.yaml, version 8).

#include <dds/dds.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/dds/qos.h"

namespace autodrive::ros2 {

/// One writer's offered QoS, in rmw's terms (rmw/types.h enum numbers).
struct OfferedQos {
  static constexpr std::int64_t kInfinite = -1;
  int history = 1;  ///< 1 keep last, 2 keep all
  std::int32_t depth = 1;
  int reliability = 1;  ///< 1 reliable, 2 best effort
  int durability = 2;   ///< 1 transient local, 2 volatile
  std::int64_t deadline_ns = kInfinite;
  std::int64_t lifespan_ns = kInfinite;
  int liveliness = 1;  ///< 1 automatic, 3 manual by topic
  std::int64_t liveliness_lease_duration_ns = kInfinite;

  bool operator==(const OfferedQos&) const = default;
};

/// The QoS a discovered writer offers (from its DCPSPublication sample's QoS).
[[nodiscard]] OfferedQos OfferedQosOf(const dds_qos_t* qos);
/// The QoS our own writers of `qos` offer.
[[nodiscard]] OfferedQos OfferedQosOf(const dds::Qos& qos);

/// The `offered_qos_profiles` YAML of rosbag2: a list with one mapping per writer.
[[nodiscard]] std::string OfferedQosProfilesYaml(const std::vector<OfferedQos>& profiles);
/// Reads `offered_qos_profiles` YAML (ours or rosbag2's); throws `InputError` on text that is
/// not such a list.
[[nodiscard]] std::vector<OfferedQos> ParseOfferedQosProfiles(std::string_view yaml);

/// The QoS to re-publish a topic with, as `ros2 bag play` chooses it: reliable unless every
/// writer was best effort, transient-local when every writer was (a latched topic), keep last
/// the largest depth (keep all when a writer kept all). Reliable keep last 10 volatile when
/// `profiles` is empty.
[[nodiscard]] dds::Qos PlaybackQos(const std::vector<OfferedQos>& profiles);

/// The QoS to read a topic with so that every writer of `offered` matches and none is slowed:
/// keep last `depth`; best effort when every writer is (as rosbag2 adapts to the offered QoS:
/// such a writer then reports no incompatible reader), else reliable also taking best-effort
/// writers (`Qos::reader_accepts_best_effort`); transient-local when every writer is (latched
/// state arrives at once; a transient-local reader would not match a volatile writer).
[[nodiscard]] dds::Qos ReaderQos(const std::vector<OfferedQos>& offered, std::int32_t depth);

/// One topic of a bag, for the metadata.
struct BagTopic {
  std::string name;  ///< ROS name
  std::string type;  ///< "pkg/msg/Type"
  std::string offered_qos_profiles;
  std::string type_hash;
  std::uint64_t message_count = 0;
};

/// rosbag2's metadata.yaml (version 8) for a one-file bag `file_name`, as the `rosbag2`
/// Metadata record's `serialized_metadata`.
[[nodiscard]] std::string Rosbag2MetadataYaml(const std::vector<BagTopic>& topics,
                                              std::uint64_t starting_time_ns,
                                              std::uint64_t duration_ns,
                                              const std::string& file_name);

}  // namespace autodrive::ros2
