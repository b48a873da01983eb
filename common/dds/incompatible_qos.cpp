#include "common/dds/incompatible_qos.h"

#include <spdlog/spdlog.h>

#include <array>
#include <utility>

namespace autodrive::dds {

std::string QosPolicyName(dds_qos_policy_id_t id) {
  switch (id) {
    case DDS_USERDATA_QOS_POLICY_ID:
      return "USER_DATA";
    case DDS_DURABILITY_QOS_POLICY_ID:
      return "DURABILITY";
    case DDS_PRESENTATION_QOS_POLICY_ID:
      return "PRESENTATION";
    case DDS_DEADLINE_QOS_POLICY_ID:
      return "DEADLINE";
    case DDS_LATENCYBUDGET_QOS_POLICY_ID:
      return "LATENCY_BUDGET";
    case DDS_OWNERSHIP_QOS_POLICY_ID:
      return "OWNERSHIP";
    case DDS_LIVELINESS_QOS_POLICY_ID:
      return "LIVELINESS";
    case DDS_PARTITION_QOS_POLICY_ID:
      return "PARTITION";
    case DDS_RELIABILITY_QOS_POLICY_ID:
      return "RELIABILITY";
    case DDS_DESTINATIONORDER_QOS_POLICY_ID:
      return "DESTINATION_ORDER";
    case DDS_HISTORY_QOS_POLICY_ID:
      return "HISTORY";
    case DDS_RESOURCELIMITS_QOS_POLICY_ID:
      return "RESOURCE_LIMITS";
    case DDS_DURABILITYSERVICE_QOS_POLICY_ID:
      return "DURABILITY_SERVICE";
    case DDS_DATA_REPRESENTATION_QOS_POLICY_ID:
      return "DATA_REPRESENTATION";
    case DDS_TYPE_CONSISTENCY_ENFORCEMENT_QOS_POLICY_ID:
      return "TYPE_CONSISTENCY_ENFORCEMENT";
    default:
      return "policy " + std::to_string(static_cast<int>(id));
  }
}

std::string RclcppQosFor(const Qos& ours, bool publisher) {
  const bool reliable = ours.reliability == Qos::Reliability::kReliable;
  const bool latched = ours.durability == Qos::Durability::kTransientLocal;
  if (publisher) {  // the node publishes to our readers
    if (!reliable || ours.reader_accepts_best_effort) {
      return "rclcpp::QoS(10) or rclcpp::SensorDataQoS()";
    }
    return latched ? "rclcpp::QoS(1).transient_local()"
                   : "rclcpp::QoS(10) (reliable, not SensorDataQoS)";
  }
  if (!reliable) return "rclcpp::SensorDataQoS() (best effort)";  // our writer: /clock
  if (latched) {
    return "rclcpp::QoS(1).transient_local() (the last sample at once; rclcpp::QoS(10) also "
           "matches)";
  }
  return "rclcpp::QoS(10) or rclcpp::SensorDataQoS() (volatile, not transient_local)";
}

std::string IncompatibleQos::Message() const {
  return "incompatible QoS on " + topic + ": " +
         (our_reader
              ? "a writer offers less " + policy + " than our reader requests; publish with "
              : "a reader requests more " + policy + " than our writer offers; subscribe with ") +
         advice;
}

namespace internal {
namespace {

// Our profile as far as the entity's DDS QoS shows it (enough for the advice).
Qos ProfileOf(dds_entity_t entity) {
  Qos q;
  dds_qos_t* qos = dds_create_qos();
  if (dds_get_qos(entity, qos) == DDS_RETCODE_OK) {
    dds_reliability_kind_t reliability = DDS_RELIABILITY_RELIABLE;
    dds_duration_t blocking = 0;
    if (dds_qget_reliability(qos, &reliability, &blocking)) {
      q.reliability = reliability == DDS_RELIABILITY_RELIABLE ? Qos::Reliability::kReliable
                                                              : Qos::Reliability::kBestEffort;
    }
    dds_durability_kind_t durability = DDS_DURABILITY_VOLATILE;
    if (dds_qget_durability(qos, &durability)) {
      q.durability = durability == DDS_DURABILITY_VOLATILE ? Qos::Durability::kVolatile
                                                           : Qos::Durability::kTransientLocal;
    }
  }
  dds_delete_qos(qos);
  return q;
}

std::string TopicOf(dds_entity_t entity) {
  std::array<char, 512> name{};
  const dds_entity_t topic = dds_get_topic(entity);
  if (topic < 0 || dds_get_name(topic, name.data(), name.size()) < 0) return "(unknown topic)";
  const std::string dds_name(name.data());
  return dds_name.rfind("rt/", 0) == 0 ? dds_name.substr(2) : dds_name;
}

void OnRequested(dds_entity_t reader, const dds_requested_incompatible_qos_status_t status,
                 void* arg) {
  static_cast<IncompatibleQosWatch*>(arg)->Report(
      reader, true, static_cast<dds_qos_policy_id_t>(status.last_policy_id));
}

void OnOffered(dds_entity_t writer, const dds_offered_incompatible_qos_status_t status, void* arg) {
  static_cast<IncompatibleQosWatch*>(arg)->Report(
      writer, false, static_cast<dds_qos_policy_id_t>(status.last_policy_id));
}

}  // namespace

IncompatibleQosWatch::IncompatibleQosWatch() : listener_(dds_create_listener(this)) {
  dds_lset_requested_incompatible_qos(listener_, OnRequested);
  dds_lset_offered_incompatible_qos(listener_, OnOffered);
}

IncompatibleQosWatch::~IncompatibleQosWatch() { dds_delete_listener(listener_); }

void IncompatibleQosWatch::SetHandler(IncompatibleQosHandler handler) {
  // Waits for a call under way: once this returns, the old handler is never called again (an
  // owner removing its handler in its destructor may then go).
  std::lock_guard lock(handler_mutex_);
  handler_ = std::move(handler);
}

void IncompatibleQosWatch::Report(dds_entity_t entity, bool reader, dds_qos_policy_id_t policy) {
  // Cyclone DDS reports a peer in another partition as incompatible (PARTITION): that is
  // another city or test run sharing the domain, by design, and nothing a ROS 2 node could
  // change (rmw_cyclonedds uses no partition). Not reported, not counted as the first.
  if (policy == DDS_PARTITION_QOS_POLICY_ID) return;
  {
    std::lock_guard lock(mutex_);
    if (!reported_.insert(entity).second) return;  // its first incompatible peer only
  }
  IncompatibleQos what;
  what.topic = TopicOf(entity);
  what.our_reader = reader;
  what.policy = QosPolicyName(policy);
  what.advice = RclcppQosFor(ProfileOf(entity), /*publisher=*/reader);
  spdlog::warn("{}", what.Message());
  std::lock_guard lock(handler_mutex_);
  if (handler_) {
    try {
      handler_(what);
    } catch (const std::exception& e) {
      spdlog::error("incompatible QoS handler: {}", e.what());
    }
  }
}

}  // namespace internal
}  // namespace autodrive::dds
