#pragma once
/// @file
/// Drives a `SimClock` from `/clock`.

#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/time.h"

namespace autodrive::dds {

/// Subscribes to `/clock` (rosgraph_msgs/Clock) and advances a `SimClock` with every message,
/// from Cyclone's listener thread. A jump back of a second or more is a simulator restart: the
/// clock starts a new session (see `SimClock`). Works with our simulator and with any ROS 2
/// simulator that publishes /clock. Not movable; the clock must outlive it.
class SimClockSubscriber {
 public:
  SimClockSubscriber(const Participant& participant, SimClock& clock);
  /// /clock messages received, and those ignored because they went back a little (reordered) or
  /// were malformed.
  [[nodiscard]] std::uint64_t received() const { return received_.load(); }
  [[nodiscard]] std::uint64_t rejected() const { return rejected_.load(); }

 private:
  SimClock& clock_;
  std::atomic<std::uint64_t> received_{0};
  std::atomic<std::uint64_t> rejected_{0};
  Reader<msg::Clock> reader_;
};

}  // namespace autodrive::dds
