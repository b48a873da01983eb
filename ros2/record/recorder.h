#pragma once
/// @file
/// The recorder of autodrive-record: discovers the topics that have writers, reads each with a
/// keep-last raw reader (which never slows a writer: it acknowledges every sample it receives
/// and overwrites its oldest when the recorder falls behind) and writes every sample into a
/// rosbag2-compatible MCAP file with its receive time (log time) and source time (publish
/// time).

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "ros2/record/mcap.h"
#include "ros2/record/rosbag2.h"

#include "common/dds/discovery.h"
#include "common/dds/participant.h"
#include "common/dds/raw.h"

namespace autodrive::ros2 {

/// Which topics to record.
struct RecordOptions {
  /// Globs (fnmatch) on ROS topic names; empty: every topic.
  std::vector<std::string> topics;
  /// Globs of topics not to record, even when `topics` names them.
  std::vector<std::string> exclude;
  /// Records sensor_msgs/msg/Image topics (cameras) too. Without it an image topic is recorded
  /// only when a `topics` glob names it.
  bool cameras = false;
  /// The readers' history depth (keep last).
  std::int32_t reader_depth = 100;
};

/// Whether `options` select the topic `ros_name` of type `ros_type` ("pkg/msg/Type").
[[nodiscard]] bool Selected(const RecordOptions& options, const std::string& ros_name,
                            const std::string& ros_type);

/// What was recorded of one topic.
struct TopicCount {
  std::string topic;  ///< ROS name
  std::string type;   ///< "pkg/msg/Type"
  std::uint64_t samples = 0;
  /// Samples DDS reports lost on the way (the reader's SAMPLE_LOST status).
  std::uint64_t lost = 0;
};

/// Records into one MCAP file while it lives, until `Stop`. Not copyable.
class Recorder {
 public:
  /// Creates `path`; throws `InputError` when it cannot.
  Recorder(const dds::Participant& participant, const std::string& path, RecordOptions options);
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  /// Stops if `Stop` was not called.
  ~Recorder();

  /// Subscribes to the selected topics whose writers were discovered since the last call.
  /// Returns how many topics it started recording. Call it periodically.
  std::size_t Discover();
  /// Stops reading, writes what was read and closes the file (summary, rosbag2 metadata).
  void Stop();
  /// Per recorded topic, in the order recording started.
  [[nodiscard]] std::vector<TopicCount> counts() const;
  /// Topics with writers that are not recorded because their type is unknown here.
  [[nodiscard]] std::set<std::string> unknown_types() const;

 private:
  struct Topic {
    std::string ros_name;
    const dds::MessageTypeInfo* type = nullptr;
    std::string qos_yaml;  ///< the channel's offered_qos_profiles
    std::uint16_t channel = 0;
    std::mutex take_mutex;  // one taker at a time; guards `sequence`
    std::uint32_t sequence = 0;
    std::atomic<std::uint64_t> samples{0};
    std::unique_ptr<dds::RawReader> reader;
  };
  void TakeAll(Topic& topic);
  void WriteLoop();

  const dds::Participant& participant_;
  std::string path_;
  RecordOptions options_;
  dds::PublicationWatcher publications_;  // writers of this participant's partition
  /// Per DDS topic name: its type and the offered QoS of each writer seen (by writer key).
  struct Seen {
    std::string type_name;
    std::map<std::string, OfferedQos> writers;
  };
  std::map<std::string, Seen> seen_;
  std::set<std::string> unknown_types_;

  mutable std::mutex file_mutex_;  // the writer, topics_
  McapWriter writer_;
  std::map<std::string, std::uint16_t> schemas_;
  std::vector<std::unique_ptr<Topic>> topics_;
  std::set<std::string> recorded_;  // DDS names

  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<McapMessage> queue_;
  bool stopping_ = false;
  bool stopped_ = false;
  std::thread write_thread_;
};

}  // namespace autodrive::ros2
