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

/// Plays `path` until its end or until `stop` becomes true; returns the messages published per
/// ROS topic. Throws `InputError` on a file it cannot read or a type it does not know.
std::map<std::string, std::uint64_t> Play(const dds::Participant& participant,
                                          const std::string& path, const PlayOptions& options,
                                          const std::atomic<bool>& stop);

}  // namespace autodrive::ros2
