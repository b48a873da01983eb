#pragma once
/// @file
/// A peer whose QoS cannot match one of our readers or writers: a ROS 2 node publishing with
/// `SensorDataQoS` (best effort) to a topic whose readers need reliable writers, or
/// subscribing `transient_local()` to a volatile stream. DDS then simply never matches them and
/// both sides stay silent; DDS's requested/offered incompatible-QoS statuses are the only trace.
/// Every participant watches them for all its readers and writers: the first incompatible peer
/// of each reader or writer gets one log line naming the topic, the policy and the QoS the peer
/// should use (`IncompatibleQos::Message`), and the participant's handler, if it has one (the
/// SCM raises an Event; docs/messaging.md, "Using it from ROS 2").

#include <dds/dds.h>

#include <functional>
#include <mutex>
#include <set>
#include <string>

#include "common/dds/qos.h"

namespace autodrive::dds {

struct IncompatibleQos {
  /// The topic's ROS name ("/autodrive/scm/operator/request"), or its DDS name when it has none.
  std::string topic;
  /// Our reader (the peer is a writer that offers too little) or our writer (the peer is a
  /// reader that asks for too much).
  bool our_reader = false;
  /// DDS's name of the policy that failed: "RELIABILITY", "DURABILITY", "DEADLINE", ...
  std::string policy;
  /// What the peer should use, in rclcpp's words: "rclcpp::QoS(10) (reliable)".
  std::string advice;
  /// One line for people: "a best-effort ... ".
  [[nodiscard]] std::string Message() const;
};

/// Called, from a Cyclone DDS thread, once for the first incompatible peer of each reader and
/// writer. Must not block.
using IncompatibleQosHandler = std::function<void(const IncompatibleQos&)>;

/// DDS's name of a QoS policy id (DDS_RELIABILITY_QOS_POLICY_ID -> "RELIABILITY").
[[nodiscard]] std::string QosPolicyName(dds_qos_policy_id_t id);

/// The rclcpp QoS a ROS 2 node should use on a topic whose readers (`publisher` true: the node
/// publishes) or writers (false: it subscribes) have profile `ours`.
[[nodiscard]] std::string RclcppQosFor(const Qos& ours, bool publisher);

namespace internal {
/// A participant's watch: a DDS listener, set on the participant, that every reader and
/// writer without one of its own for these statuses hands its incompatible-QoS statuses to
/// (Cyclone DDS passes a status an entity's listener leaves unset up to its parent's).
class IncompatibleQosWatch {
 public:
  IncompatibleQosWatch();
  IncompatibleQosWatch(const IncompatibleQosWatch&) = delete;
  IncompatibleQosWatch& operator=(const IncompatibleQosWatch&) = delete;
  ~IncompatibleQosWatch();

  [[nodiscard]] const dds_listener_t* listener() const { return listener_; }
  void SetHandler(IncompatibleQosHandler handler);
  /// From the listener: logs and hands on the first report of `entity`.
  void Report(dds_entity_t entity, bool reader, dds_qos_policy_id_t policy);

 private:
  dds_listener_t* listener_;
  std::mutex mutex_;  // reported_
  std::set<dds_entity_t> reported_;
  std::mutex handler_mutex_;  // held while the handler runs
  IncompatibleQosHandler handler_;
};
}  // namespace internal

}  // namespace autodrive::dds
