#include "ros2/record/player.h"

#include <memory>
#include <thread>
#include <vector>

#include "ros2/record/mcap.h"
#include "ros2/record/rosbag2.h"

#include "common/dds/raw.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::ros2 {

namespace {

/// rosgraph_msgs/Clock {builtin_interfaces/Time clock} as little-endian XCDR1.
std::vector<std::byte> ClockCdr(std::uint64_t ns) {
  const auto sec = static_cast<std::uint32_t>(ns / 1000000000U);
  const auto nsec = static_cast<std::uint32_t>(ns % 1000000000U);
  std::vector<std::byte> out = {std::byte{0}, std::byte{1}, std::byte{0}, std::byte{0}};
  for (std::uint32_t v : {sec, nsec}) {
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFFU));
  }
  return out;
}

}  // namespace

PlayResult Play(const dds::Participant& participant, const std::string& path,
                const PlayOptions& options, const std::atomic<bool>& stop) {
  AUTODRIVE_THROW_UNLESS(options.rate > 0, "--rate must be > 0, got " << options.rate);
  McapReader reader(path);
  std::map<std::uint16_t, std::unique_ptr<dds::RawWriter>> writers;
  PlayResult result;
  for (const auto& [id, channel] : reader.channels()) {
    const auto schema = reader.schemas().find(channel.schema_id);
    const dds::MessageTypeInfo* type =
        schema == reader.schemas().end() ? nullptr : dds::FindMessageType(schema->second.name);
    if (channel.message_encoding != "cdr") {
      result.skipped[channel.topic] =
          "message encoding '" + channel.message_encoding + "', not cdr";
    } else if (schema == reader.schemas().end()) {
      result.skipped[channel.topic] = "no schema";
    } else if (type == nullptr) {
      result.skipped[channel.topic] = "type " + schema->second.name + " is not known here";
    }
    if (type == nullptr || channel.message_encoding != "cdr") continue;
    std::vector<OfferedQos> offered;
    if (const auto it = channel.metadata.find("offered_qos_profiles");
        it != channel.metadata.end()) {
      offered = ParseOfferedQosProfiles(it->second);
    }
    writers[id] = std::make_unique<dds::RawWriter>(participant, dds::topics::ToDds(channel.topic),
                                                   type->descriptor, PlaybackQos(offered));
    result.published[channel.topic] = 0;
  }
  AUTODRIVE_THROW_UNLESS(!writers.empty(), path << ": no topic to play (" << result.skipped.size()
                                                << " topics, none of a type known here)");
  std::unique_ptr<dds::RawWriter> clock;
  if (options.clock) {
    const auto spec = dds::topics::Clock();
    const dds::MessageTypeInfo* type = dds::FindMessageType("rosgraph_msgs/msg/Clock");
    AUTODRIVE_THROW_UNLESS(type != nullptr, "rosgraph_msgs/msg/Clock is not registered");
    clock = std::make_unique<dds::RawWriter>(participant, spec.name, type->descriptor, spec.qos);
  }
  if (options.wait_for_readers > std::chrono::steady_clock::duration::zero()) {
    const auto deadline = std::chrono::steady_clock::now() + options.wait_for_readers;
    for (auto& [id, w] : writers) {
      const auto left = deadline - std::chrono::steady_clock::now();
      if (left <= std::chrono::steady_clock::duration::zero()) break;
      (void)w->WaitForReaders(1, left);
    }
  }

  bool first = true;
  std::uint64_t first_time = 0;
  const auto start = std::chrono::steady_clock::now();
  reader.ReadMessages([&](const McapMessage& m) {
    if (stop.load()) return;
    if (first) {
      first_time = m.log_time;
      first = false;
    }
    const double offset_s =
        static_cast<double>(m.log_time > first_time ? m.log_time - first_time : 0) / 1e9 /
        options.rate;
    const auto due = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>(offset_s));
    while (!stop.load() && std::chrono::steady_clock::now() < due) {
      std::this_thread::sleep_until(
          std::min(due, std::chrono::steady_clock::now() + std::chrono::milliseconds(100)));
    }
    if (stop.load()) return;
    if (clock) clock->Write(ClockCdr(m.log_time));
    const auto writer = writers.find(m.channel_id);
    if (writer == writers.end()) return;  // a skipped topic
    const std::string& topic = reader.channels().at(m.channel_id).topic;
    try {
      writer->second->Write(m.data);
      ++result.published[topic];
    } catch (const InputError&) {
      ++result.refused[topic];  // not a sample of its type: the others still play
    }
  });
  // Let reliable readers get the last samples before the writers go.
  for (auto& [id, w] : writers) (void)w->WaitForAcks(std::chrono::seconds(2));
  return result;
}

}  // namespace autodrive::ros2
