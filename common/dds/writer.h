#pragma once
/// @file
/// Typed DDS writer.

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
/// Number of readers currently matched with `writer`.
std::uint32_t MatchedReaders(dds_entity_t writer);
/// Waits (polling the matched status, steady clock) until `writer` has at least `n` readers.
bool WaitForReaders(dds_entity_t writer, std::uint32_t n,
                    std::chrono::steady_clock::duration timeout);
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
        writer_(dds_create_writer(participant.publisher(), topic_.handle(),
                                  internal::MakeQos(qos).get(), nullptr),
                "dds_create_writer(" + topic_name + ")") {}
  /// A writer for a topic of the catalogue (common/dds/topics.h).
  Writer(const Participant& participant, const TopicSpec<T>& spec)
      : Writer(participant, spec.name, spec.qos) {}

  /// Publishes one sample. Throws `DdsError` when Cyclone fails (for example a reliable write
  /// that timed out on a full keep-all history).
  void Write(const T& sample) {
    internal::ThrowIfError(dds_write(writer_.handle(), &sample), "dds_write");
  }
  void Write(const Message<T>& message) { Write(message.get()); }

  /// Readers currently matched.
  [[nodiscard]] std::uint32_t matched_readers() const {
    return internal::MatchedReaders(writer_.handle());
  }
  /// Blocks until at least `n` readers match or `timeout` (steady clock) passes.
  bool WaitForReaders(std::uint32_t n, std::chrono::steady_clock::duration timeout) const {
    return internal::WaitForReaders(writer_.handle(), n, timeout);
  }
  [[nodiscard]] const std::string& topic_name() const { return topic_name_; }
  [[nodiscard]] dds_entity_t handle() const { return writer_.handle(); }

 private:
  std::string topic_name_;
  Entity topic_;  // destroyed after the writer
  Entity writer_;
};

}  // namespace autodrive::dds
