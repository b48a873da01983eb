#pragma once
/// @file
/// The simulator service's background traffic (service.cpp): SUMO's objects as
/// `autodrive-traffic` publishes them on `/autodrive/scm/traffic`, taken once per control
/// period and put in the world (boxes for the LIDARs and the physics, looks for the cameras),
/// and the collisions of the cars with them (`TouchLog`, service_rules.h). What an object is
/// and where it is placed is vehicle_sim/traffic.h.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/time.h"
#include "vehicle_sim/internal/service_rules.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/traffic.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim::internal {

/// A car and a background object that have not touched for this long touch anew: a car pressed
/// against one is one collision, not one per step that its contact flickers.
inline constexpr Duration kTouchGap = std::chrono::seconds(1);

/// The newest background traffic and what the cars did with it. Not copyable or movable (its
/// reader is not). For the loop's thread only, but `collisions()` from any.
class BackgroundTraffic {
 public:
  /// `read`: whether to read the topic at all (a reader on `participant`, which must outlive
  /// it); `car_names`: the world's cars by index (objects' box ids come after theirs);
  /// `looks`: whether the cameras need the objects' looks.
  BackgroundTraffic(const dds::Participant& participant, bool read,
                    std::vector<std::string> car_names, bool looks);
  BackgroundTraffic(const BackgroundTraffic&) = delete;
  BackgroundTraffic& operator=(const BackgroundTraffic&) = delete;

  /// Takes the newest message and places its objects in `world` for this period, at `now`:
  /// as the message has them (`extrapolate` false: lockstep and fast mode, reproducible), or
  /// moved along their heading by their speed for the message's age (real time; at most
  /// kMaxTrafficExtrapolation). Nothing changes while no message came and the poses stay
  /// where they are. A bad message's objects are left out, logged every 100 bad messages.
  void Take(Time now, bool extrapolate, World& world);

  /// Counts and logs the cars that ran into an object in the world's last step.
  void NoteContacts(const World& world);

  /// The objects' boxes as placed for this period.
  [[nodiscard]] const std::vector<DynamicBox>& boxes() const { return boxes_; }
  /// The objects' looks as placed for this period (empty without cameras).
  [[nodiscard]] const std::vector<RenderTraffic>& looks() const { return looks_; }
  /// Collisions so far. Thread-safe.
  [[nodiscard]] std::int64_t collisions() const { return collisions_.load(); }

 private:
  // Reads the newest message into `objects_` (and its stamp); false when none came.
  bool TakeNewest(Time now);

  std::unique_ptr<dds::Reader<msg::TrafficObjects>> reader_;
  std::vector<std::string> car_names_;
  bool want_looks_;
  // The newest message (`incoming_` takes, so that a failed take never spoils the newest).
  dds::Message<msg::TrafficObjects> newest_, incoming_;
  std::vector<TrafficObject> objects_;    // as the newest message gave them
  Time stamp_;                            // the newest message's
  std::optional<Duration> placed_after_;  // the extrapolation the placed poses have
  std::vector<DynamicBox> boxes_;         // ids after the cars'
  std::vector<RenderTraffic> looks_;
  std::int64_t messages_ = 0;
  std::int64_t bad_messages_ = 0;
  TouchLog touches_{kTouchGap};
  std::atomic<std::int64_t> collisions_{0};
};

}  // namespace autodrive::vehicle_sim::internal
