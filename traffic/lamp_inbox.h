#pragma once
/// @file
/// The lamps the city's lights report (`signal_<i>/state`, one latched topic per head), taken
/// as they arrive. A light reports only changes, so a step of the co-simulation sees a handful
/// of the city's heads change; polling every head's reader each step cost more than SUMO's
/// own step (about 0.8 ms for the 4,096 heads of a 32 x 32 grid). Here each reader hands its
/// samples over on Cyclone's thread as they arrive, and a step takes only what came.

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/ids.h"

namespace autodrive::traffic {

class LampInbox {
 public:
  struct Lamp {
    SignalHeadId head;
    int lamp = 0;  ///< the wire value of `signal_<i>/state`
  };

  /// Subscribes to every head in `heads`. `participant` must outlive it.
  LampInbox(const dds::Participant& participant, const std::vector<SignalHeadId>& heads);
  LampInbox(const LampInbox&) = delete;
  LampInbox& operator=(const LampInbox&) = delete;
  /// Stops the readers first (waiting for a running hand-over).
  ~LampInbox();

  /// Replaces `out` with what arrived since the last call, in arrival order (a head's reports
  /// keep their order). Thread-safe; takes no longer than copying what arrived.
  void Take(std::vector<Lamp>& out);
  /// Reports received so far.
  [[nodiscard]] std::uint64_t received() const { return received_.load(); }

 private:
  void Drain(SignalHeadId head, dds::Reader<msg::Int32>& reader);

  std::mutex mutex_;
  std::vector<Lamp> arrived_;
  std::atomic<std::uint64_t> received_{0};
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> readers_;
};

}  // namespace autodrive::traffic
