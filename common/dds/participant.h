#pragma once
/// @file
/// A DDS domain participant with the publisher and subscriber every writer and reader of a
/// process uses.

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "common/dds/entity.h"

namespace autodrive::dds {

/// How a process joins the lab's DDS domain.
struct ParticipantOptions {
  /// DDS domain id. Unset: `ROS_DOMAIN_ID` from the environment if set (as ROS 2 does), else
  /// Cyclone's default (its configuration, usually 0).
  std::optional<std::uint32_t> domain_id;
  /// Partition for this process's publisher and subscriber: separates cities that share a
  /// domain. Empty (the default) is the default partition, which ROS 2 nodes use.
  std::string partition;
  /// Cyclone XML configuration (text or `file://` URI) used to create the domain. Empty: Cyclone
  /// reads `CYCLONEDDS_URI` as usual. Only the first participant of a domain in a process can
  /// set it.
  std::string cyclone_config;
};

/// A participant in one DDS domain, owning one publisher and one subscriber. Move-only.
/// Deleting it deletes every writer, reader and waitset created from it.
class Participant {
 public:
  /// Joins the domain. Throws `DdsError` when Cyclone cannot (bad configuration, no network
  /// interface), `InputError` for a bad ROS_DOMAIN_ID.
  explicit Participant(const ParticipantOptions& options = {});

  [[nodiscard]] dds_entity_t handle() const { return participant_.handle(); }
  [[nodiscard]] dds_entity_t publisher() const { return publisher_.handle(); }
  [[nodiscard]] dds_entity_t subscriber() const { return subscriber_.handle(); }
  [[nodiscard]] std::uint32_t domain_id() const { return domain_id_; }
  [[nodiscard]] const std::string& partition() const { return partition_; }

  /// Records that `topic_name` carries `type_name` in this participant. Cyclone lets one name
  /// carry two types (whose readers and writers then silently never match); we refuse it.
  /// Throws `InputError` naming the topic and both types. Thread-safe.
  void ClaimTopic(const std::string& topic_name, std::string_view type_name) const;

 private:
  Entity domain_;  // only when a configuration was given; deleted last
  Entity participant_;
  Entity publisher_;
  Entity subscriber_;
  std::uint32_t domain_id_ = 0;
  std::string partition_;
  // Topic name -> type name. Behind a pointer so the participant stays movable.
  struct TopicTypes {
    std::mutex mutex;
    std::map<std::string, std::string, std::less<>> types;
  };
  std::unique_ptr<TopicTypes> topic_types_ = std::make_unique<TopicTypes>();
};

}  // namespace autodrive::dds
