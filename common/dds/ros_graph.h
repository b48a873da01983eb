#pragma once
/// @file
/// Presence in the ROS 2 graph. A ROS 2 tool finds topics and types from DDS discovery alone,
/// but nodes (`ros2 node list`, `ros2 node info`, which endpoint belongs to which node) only
/// from `ros_discovery_info`: each participant of rmw_cyclonedds publishes there a
/// `rmw_dds_common/msg/ParticipantEntitiesInfo` naming its nodes and the GIDs (DDS GUIDs) of
/// their readers and writers (reliable, transient-local, keep last 1), and again whenever they
/// change. A participant made with `ParticipantOptions::ros_node` does the same for one node.
///
/// Jazzy (and Iron, Rolling) spell a GID in 16 bytes, Humble in 24 (the GUID then 8 zero
/// bytes), under the same type name: `ROS_DISTRO=humble` (or foxy, galactic) selects Humble's.

#include <dds/dds.h>

#include <memory>
#include <string>
#include <string_view>

namespace autodrive::dds {

class Participant;

/// A ROS 2 node's name: namespace ("/autodrive") and name ("scm").
struct RosNode {
  std::string node_namespace = "/";
  std::string name;
  bool operator==(const RosNode&) const = default;
  /// "/autodrive/scm".
  [[nodiscard]] std::string FullName() const;
};

/// The node a process appears as, documented in docs/messaging.md ("The ROS 2 graph"):
/// - a process autodrive-city started: `/autodrive/<its name in the city's process table>`
///   (the launcher gives it as AUTODRIVE_PROCESS_NAME), e.g. /autodrive/scm, /autodrive/lights,
///   /autodrive/driver_nigel_1;
/// - else the node its DDS identity names: "/autodrive/infra/small_town_lights" is
///   /autodrive/infra/small_town_lights (namespace /autodrive/infra).
/// Characters a ROS name cannot hold become '_', and a token starting with a digit gets a
/// leading '_'.
[[nodiscard]] RosNode RosNodeFor(std::string_view identity);

/// Which `ros_discovery_info` layout this process writes.
enum class RosGidLayout { kJazzy, kHumble };
/// From ROS_DISTRO: humble, galactic or foxy give `kHumble`; anything else, unset included,
/// `kJazzy`.
[[nodiscard]] RosGidLayout RosGidLayoutFromEnvironment();

namespace internal {

class RosGraph;

/// Lists one reader or writer under its participant's node while it lives. Move-only; empty
/// when the participant has no node.
class RosGraphEntry {
 public:
  RosGraphEntry() = default;
  RosGraphEntry(std::shared_ptr<RosGraph> graph, dds_entity_t endpoint, bool reader);
  RosGraphEntry(RosGraphEntry&& other) noexcept;
  RosGraphEntry& operator=(RosGraphEntry&& other) noexcept;
  RosGraphEntry(const RosGraphEntry&) = delete;
  RosGraphEntry& operator=(const RosGraphEntry&) = delete;
  ~RosGraphEntry() { Reset(); }

 private:
  void Reset() noexcept;
  std::shared_ptr<RosGraph> graph_;
  dds_guid_t guid_{};
  bool reader_ = false;
};

/// A participant's node and its `ros_discovery_info` writer (common/dds/ros_graph.cpp).
std::shared_ptr<RosGraph> MakeRosGraph(const Participant& participant, RosNode node,
                                       RosGidLayout layout);

}  // namespace internal
}  // namespace autodrive::dds
