#pragma once
/// @file
/// A DDS domain participant with the publisher and subscriber every writer and reader of a
/// process uses.

#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "common/dds/entity.h"
#include "common/dds/incompatible_qos.h"
#include "common/dds/ros_graph.h"
#include "common/dds/security.h"

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
  /// DDS Security (see common/dds/security.h and docs/security.md). Unset: as ROS 2 does, from
  /// the environment (`SecurityOptions::FromEnvironment()`: ROS_SECURITY_ENABLE,
  /// ROS_SECURITY_STRATEGY, ROS_SECURITY_KEYSTORE, ROS_SECURITY_ENCLAVE_OVERRIDE), which
  /// leaves the participant unsecured unless ROS_SECURITY_ENABLE=true. Set it to override the
  /// environment; `SecurityOptions{}` is unsecured whatever the environment says.
  /// (The initializer keeps `ParticipantOptions{domain, partition, config}` free of
  /// -Wmissing-field-initializers.)
  std::optional<SecurityOptions> security = std::nullopt;
  /// The ROS 2 node this participant appears as (`ros2 node list`): it publishes the node and
  /// its readers and writers on `ros_discovery_info` (common/dds/ros_graph.h). Unset: no node,
  /// as for a tool's or a test's participant. `ProgramOptions` sets it for every program.
  std::optional<RosNode> ros_node = std::nullopt;
};

namespace internal {
/// Records, while it lives, that this process has a participant in a DDS domain, secured or
/// not. Cyclone DDS 0.10.2 cannot hold both kinds in one domain of one process: after a secured
/// participant, creating an unsecured one fails; after an unsecured one, creating a secured one
/// leaves the unsecured one silently matching nothing. Move-only.
class DomainSecurityClaim {
 public:
  DomainSecurityClaim() = default;
  /// Throws `InputError` when this process has a participant of the other kind in `domain`.
  DomainSecurityClaim(std::uint32_t domain, bool secured);
  DomainSecurityClaim(DomainSecurityClaim&& other) noexcept;
  DomainSecurityClaim& operator=(DomainSecurityClaim&& other) noexcept;
  DomainSecurityClaim(const DomainSecurityClaim&) = delete;
  DomainSecurityClaim& operator=(const DomainSecurityClaim&) = delete;
  ~DomainSecurityClaim() { Release(); }

 private:
  void Release() noexcept;
  std::optional<std::uint32_t> domain_;
  bool secured_ = false;
};
}  // namespace internal

/// A participant in one DDS domain, owning one publisher and one subscriber. Move-only.
/// Deleting it deletes every writer, reader and waitset created from it.
class Participant {
 public:
  /// Joins the domain. Throws `DdsError` when Cyclone cannot (bad configuration, no network
  /// interface, or with security an identity, governance or permissions document that Cyclone
  /// rejects: its log on stderr says which), `InputError` for a bad ROS_DOMAIN_ID and for the
  /// security settings `ResolveEnclave` and `SecurityPluginDirectory` refuse (no keystore when
  /// enforced, a missing or unreadable enclave file, no plugins) and when this process already
  /// has a participant of the other kind (secured or not) in the same domain, which Cyclone
  /// DDS cannot serve (see `internal::DomainSecurityClaim`).
  explicit Participant(const ParticipantOptions& options = {});

  [[nodiscard]] dds_entity_t handle() const { return participant_.handle(); }
  [[nodiscard]] dds_entity_t publisher() const { return publisher_.handle(); }
  [[nodiscard]] dds_entity_t subscriber() const { return subscriber_.handle(); }
  [[nodiscard]] std::uint32_t domain_id() const { return domain_id_; }
  [[nodiscard]] const std::string& partition() const { return partition_; }
  /// True when DDS Security secures this participant.
  [[nodiscard]] bool secured() const { return !enclave_.empty(); }
  /// The enclave this participant authenticates as ("/autodrive/scm"); empty when unsecured.
  [[nodiscard]] const std::string& enclave() const { return enclave_; }

  /// Waits until every matched reliable reader acknowledged every sample that any writer of
  /// this participant wrote, or `timeout` (steady clock, for all of them together) passes.
  /// True when they did; a writer deleted meanwhile (by another thread) counts as done. A
  /// lockstep controller calls it before it answers a step.
  [[nodiscard]] bool WaitForAcks(std::chrono::steady_clock::duration timeout) const;

  /// Also hands the first incompatible peer of each reader and writer to `handler` (after the
  /// log line every participant writes; common/dds/incompatible_qos.h). Replaces an earlier
  /// handler. Thread-safe; `handler` runs on a Cyclone DDS thread and must not block.
  void OnIncompatibleQos(IncompatibleQosHandler handler) const {
    qos_watch_->SetHandler(std::move(handler));
  }
  /// The ROS 2 node it appears as, if any.
  [[nodiscard]] const std::optional<RosNode>& ros_node() const { return ros_node_; }
  /// Lists `endpoint` (a reader or writer of this participant) under its node on
  /// `ros_discovery_info` while the returned entry lives; an empty entry without a node.
  [[nodiscard]] internal::RosGraphEntry ListInRosGraph(dds_entity_t endpoint, bool reader) const {
    return internal::RosGraphEntry(ros_graph_, endpoint, reader);
  }

  /// Records that `topic_name` carries `type_name` in this participant. Cyclone lets one name
  /// carry two types (whose readers and writers then silently never match); we refuse it.
  /// Throws `InputError` naming the topic and both types. Thread-safe.
  void ClaimTopic(const std::string& topic_name, std::string_view type_name) const;

 private:
  internal::DomainSecurityClaim claim_;  // released after everything below is deleted
  // Behind a pointer (the listener's argument), deleted after the participant.
  std::unique_ptr<internal::IncompatibleQosWatch> qos_watch_ =
      std::make_unique<internal::IncompatibleQosWatch>();
  Entity domain_;  // only when a configuration was given
  Entity participant_;
  Entity publisher_;
  Entity subscriber_;
  std::uint32_t domain_id_ = 0;
  std::string partition_;
  std::string enclave_;
  // Topic name -> type name. Behind a pointer so the participant stays movable.
  struct TopicTypes {
    std::mutex mutex;
    std::map<std::string, std::string, std::less<>> types;
  };
  std::unique_ptr<TopicTypes> topic_types_ = std::make_unique<TopicTypes>();
  std::optional<RosNode> ros_node_;
  // Last, so that its writer goes before the participant (entries of live readers and writers
  // share it).
  std::shared_ptr<internal::RosGraph> ros_graph_;
};

}  // namespace autodrive::dds
