#pragma once
/// @file
/// Samples as serialized CDR, for programs that carry samples without knowing their type at
/// compile time: the recorder and its playback (ros2/record), wire checks. A raw sample is the
/// bytes DDS puts on the wire for it: the 4-byte encapsulation header (`00 01 00 00` for
/// little-endian XCDR1, as rmw_cyclonedds and Cyclone write) followed by the payload, exactly
/// what MCAP's `cdr` message encoding holds.

#include <dds/dds.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/dds/participant.h"
#include "common/dds/qos.h"
#include "common/dds/reader.h"

namespace autodrive::dds {

/// A registered message type (common/dds/messages.h) by name: its DDS type name
/// ("std_msgs::msg::dds_::Header_"), its ROS type name ("std_msgs/msg/Header") and descriptor.
struct MessageTypeInfo {
  std::string dds_type_name;
  std::string ros_type_name;
  const dds_topic_descriptor_t* descriptor = nullptr;
};

/// Every registered message type, in the order of `AllMessageDescriptors()`. Humble's
/// `ros_discovery_info` type (same DDS name as Jazzy's) is not among them.
[[nodiscard]] const std::vector<MessageTypeInfo>& MessageTypes();
/// The type with DDS name or ROS name `name` ("pkg/msg/Type" or "pkg::msg::dds_::Type_");
/// nullptr when no registered type has it.
[[nodiscard]] const MessageTypeInfo* FindMessageType(std::string_view name);
/// "pkg/msg/Type" for a DDS type name "pkg::msg::dds_::Type_" (rmw_cyclonedds' rule read
/// backwards); empty when the name is not of that form.
[[nodiscard]] std::string RosTypeName(std::string_view dds_type_name);

/// One received sample, serialized.
struct RawSample {
  /// Encapsulation header and payload, as received.
  std::vector<std::byte> cdr;
  /// The writer's DDS source timestamp, ns since the Unix epoch.
  std::int64_t source_timestamp_ns = 0;
  /// Identifies the writer (unique in this process).
  dds_instance_handle_t publication_handle = 0;
};

/// Reads one topic's samples without deserializing them. Its topic, QoS (including a
/// `Qos::reader_accepts_best_effort` profile), ROS graph entry, waiting and listener delivery
/// are those of `Reader<T>`. Not movable.
class RawReader {
 public:
  RawReader(const Participant& participant, const std::string& topic_name,
            const dds_topic_descriptor_t* descriptor, const Qos& qos);
  RawReader(const RawReader&) = delete;
  RawReader& operator=(const RawReader&) = delete;

  /// Takes the next valid sample into `sample` (reusing its buffer). False when none waits.
  bool Take(RawSample& sample);
  bool WaitForData(std::chrono::steady_clock::duration timeout) {
    return base_.WaitForData(timeout);
  }
  /// `callback()` runs on a Cyclone thread when data arrives; it should take the samples.
  void OnDataAvailable(std::function<void()> callback) {
    base_.SetOnDataAvailable(std::move(callback));
  }
  [[nodiscard]] std::uint32_t matched_writers() const { return base_.matched_writers(); }
  bool WaitForWriters(std::uint32_t n, std::chrono::steady_clock::duration timeout) const {
    return base_.WaitForWriters(n, timeout);
  }
  [[nodiscard]] const std::string& topic_name() const { return base_.topic_name(); }
  [[nodiscard]] dds_entity_t handle() const { return base_.handle(); }

 private:
  internal::ReaderBase base_;
};

/// Writes serialized samples of one type to one topic. The bytes are checked against the type
/// (a malformed or truncated sample, or one of another type's shape, is refused with
/// `InputError`), then published as Cyclone publishes a typed sample: a payload written by
/// Cyclone, rmw_cyclonedds or any canonical little-endian XCDR1 writer goes out byte for
/// byte as it came. Big-endian and XCDR2 input is accepted and re-encoded. Move-only.
class RawWriter {
 public:
  RawWriter(const Participant& participant, const std::string& topic_name,
            const dds_topic_descriptor_t* descriptor, const Qos& qos);

  /// Publishes one serialized sample (encapsulation header and payload).
  void Write(std::span<const std::byte> cdr);
  [[nodiscard]] std::uint32_t matched_readers() const {
    return internal::MatchedReaders(writer_.handle());
  }
  bool WaitForReaders(std::uint32_t n, std::chrono::steady_clock::duration timeout) const {
    return internal::WaitForReaders(writer_.handle(), n, timeout);
  }
  bool WaitForAcks(std::chrono::steady_clock::duration timeout) const {
    return internal::WaitForAcks(writer_.handle(), timeout);
  }
  [[nodiscard]] const std::string& topic_name() const { return topic_name_; }
  [[nodiscard]] dds_entity_t handle() const { return writer_.handle(); }

 private:
  std::string topic_name_;
  const dds_topic_descriptor_t* descriptor_;
  Entity topic_;
  Entity writer_;
  internal::RosGraphEntry ros_graph_entry_;
  std::vector<std::byte> scratch_;  // the payload being checked (normalised in place)
};

}  // namespace autodrive::dds
