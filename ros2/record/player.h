#pragma once
/// @file
/// The player of autodrive-record: re-publishes an MCAP recording's messages, byte for byte
/// through raw writers, each topic with the QoS its writers offered when it was recorded
/// (transient-local for latched topics), at the recorded pace scaled by a rate.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <string>

#include "common/dds/participant.h"

namespace autodrive::ros2 {

struct PlayOptions {
  /// Pace: 2 plays twice as fast. Must be > 0.
  double rate = 1.0;
  /// Also publishes /clock (rosgraph_msgs/Clock) with each message's log time.
  bool clock = false;
  /// Waits this long for each topic's first reader before playing (discovery).
  std::chrono::steady_clock::duration wait_for_readers = std::chrono::seconds(0);
};

/// What `Play` did.
struct PlayResult {
  /// Messages published per ROS topic.
  std::map<std::string, std::uint64_t> published;
  /// Messages not published per ROS topic: bytes that are not a sample of the topic's type.
  std::map<std::string, std::uint64_t> refused;
  /// Topics not played, each with why (a type not known here, an encoding not cdr, no schema):
  /// the rest of the file is played, as `ros2 bag play` does.
  std::map<std::string, std::string> skipped;
};

/// Plays `path` until its end or until `stop` becomes true. Throws `InputError` on a file it
/// cannot read or one with no topic it can play.
PlayResult Play(const dds::Participant& participant, const std::string& path,
                const PlayOptions& options, const std::atomic<bool>& stop);

}  // namespace autodrive::ros2
