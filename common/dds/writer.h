#pragma once
/// @file
/// Typed DDS writer.

#include <chrono>
#include <cstdint>
#include <string>

#include "common/dds/entity.h"
#include "common/dds/message.h"
#include "common/dds/participant.h"
#include "common/dds/qos.h"
#include "common/dds/topic_spec.h"
#include "common/time.h"

namespace autodrive::dds {

namespace internal {
/// Creates the topic `name` of type `descriptor` in `participant`. Throws `InputError` when
/// the participant already uses the name with another type.
Entity CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                   const std::string& name);
/// The QoS of a reader or writer of type `descriptor`: the profile, and USER_DATA
/// `typehash=RIHS01_...;` as rmw_cyclonedds gives every endpoint (common/dds/type_hashes.h).
QosPtr MakeEndpointQos(const Qos& qos, const dds_topic_descriptor_t* descriptor);
/// Number of readers currently matched with `writer`.
std::uint32_t MatchedReaders(dds_entity_t writer);
/// Waits until `writer` has at least `n` matched readers or `timeout` (steady clock) passes.
/// Blocks on a waitset triggered by the publication-matched status (the writer's status mask
/// becomes DDS_PUBLICATION_MATCHED_STATUS only), re-checking the count at least once a second.
bool WaitForReaders(dds_entity_t writer, std::uint32_t n,
                    std::chrono::steady_clock::duration timeout);
/// Waits until every matched reader acknowledged every sample `writer` wrote, or `timeout`
/// passes. True when they did.
bool WaitForAcks(dds_entity_t writer, std::chrono::steady_clock::duration timeout);
}  // namespace internal

/// Writes samples of `T` to one topic. Move-only; deleting it unregisters the writer.
template <MessageType T>
class Writer {
 public:
  /// Creates the topic (if needed) and the writer. `topic_name` is a DDS name: use the helpers
  /// in common/dds/topics.h (`rt/...`). Throws `DdsError` when Cyclone refuses (for example a
  /// topic of the same name with another type).
  Writer(const Participant& participant, const std::string& topic_name, const Qos& qos)
      : topic_name_(topic_name),
        topic_(internal::CreateTopic(participant, MessageTraits<T>::descriptor(), topic_name)),
        writer_(dds_create_writer(
                    participant.publisher(), topic_.handle(),
                    internal::MakeEndpointQos(qos, MessageTraits<T>::descriptor()).get(), nullptr),
                "dds_create_writer(" + topic_name + ")"),
        ros_graph_entry_(participant.ListInRosGraph(writer_.handle(), /*reader=*/false)) {}
  /// A writer for a topic of the catalogue (common/dds/topics.h).
  Writer(const Participant& participant, const TopicSpec<T>& spec)
      : Writer(participant, spec.name, spec.qos) {}

  /// Publishes one sample. Throws `DdsError` when Cyclone fails (for example a reliable write
  /// that timed out on a full keep-all history).
  void Write(const T& sample) {
    internal::ThrowIfError(dds_write(writer_.handle(), &sample), "dds_write");
  }
  void Write(const Message<T>& message) { Write(message.get()); }
  /// Writes `sample` with `source_time` as its DDS source timestamp: the time the sample stands
  /// for, for a type without a header (a reader sees it in `SampleInfo::source_timestamp_ns`).
  void WriteAt(const T& sample, Time source_time) {
    internal::ThrowIfError(
        dds_write_ts(writer_.handle(), &sample,
                     static_cast<dds_time_t>(source_time.time_since_epoch().count())),
        "dds_write_ts");
  }

  /// Readers currently matched.
  [[nodiscard]] std::uint32_t matched_readers() const {
    return internal::MatchedReaders(writer_.handle());
  }
  /// Blocks until at least `n` readers match or `timeout` (steady clock) passes; true when
  /// they do. Wakes on DDS's publication-matched status (no polling). Throws `DdsError`
  /// when Cyclone fails.
  bool WaitForReaders(std::uint32_t n, std::chrono::steady_clock::duration timeout) const {
    return internal::WaitForReaders(writer_.handle(), n, timeout);
  }
  /// Blocks until every matched reader has acknowledged every sample written so far, or
  /// `timeout` (steady clock) passes; true when they have (at once with no reader or a
  /// best-effort writer). Lets a burst of writes to a keep-all writer pace itself instead of
  /// filling the history and failing after `max_blocking`. Throws `DdsError` when Cyclone
  /// fails.
  bool WaitForAcks(std::chrono::steady_clock::duration timeout) const {
    return internal::WaitForAcks(writer_.handle(), timeout);
  }
  [[nodiscard]] const std::string& topic_name() const { return topic_name_; }
  [[nodiscard]] dds_entity_t handle() const { return writer_.handle(); }

 private:
  std::string topic_name_;
  Entity topic_;  // destroyed after the writer
  Entity writer_;
  internal::RosGraphEntry ros_graph_entry_;
};

}  // namespace autodrive::dds
