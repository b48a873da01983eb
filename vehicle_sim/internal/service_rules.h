#pragma once
/// @file
/// The simulator service's pure rules, on the simulated clock and without DDS, so that they are
/// tested in-process (service_rules_test.cpp): when a car's command stream counts as stopped,
/// and when a car touching a background object has run into it. The service (service.cpp)
/// feeds them what its DDS edge took and logs what they decide.

#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include "common/time.h"

namespace autodrive::vehicle_sim::internal {

/// A car's command stream against its time-out: a car that had commands and then none for
/// longer than the time-out is held still (throttle 0), as the real car's firmware does, until
/// a command comes again. Before its first command a car is never held. Copyable.
class CommandWatch {
 public:
  /// What `Update` changed.
  enum class Change : std::uint8_t {
    kNone,      ///< as before
    kResumed,   ///< commands again after a time-out
    kTimedOut,  ///< no command for longer than the time-out: held from now on
  };

  /// One control period at simulated time `now`: `fresh` when a valid command arrived in it.
  Change Update(bool fresh, Duration now, Duration timeout);

  /// Whether the car is held still now.
  [[nodiscard]] bool timed_out() const { return timed_out_; }

 private:
  Duration last_command_{0};
  bool timed_out_ = false;
  bool ever_commanded_ = false;
};

/// Which contacts between cars and background objects are collisions: a car and an object that
/// touch after not touching for longer than `gap` (or for the first time) have run into each
/// other; touching on, or again within `gap` (a contact that flickers from step to step), is the
/// same collision. Copyable.
class TouchLog {
 public:
  /// `gap`: how long a car and an object must not touch before touching counts anew.
  explicit TouchLog(Duration gap) : gap_(gap) {}

  /// Car `vehicle` touches the object `object` (its id) at simulated time `now`. True when
  /// this is a new collision.
  bool Touch(int vehicle, const std::string& object, Duration now);

  /// Forgets the pairs that have not touched for longer than the gap at `now` (call once per
  /// step, after its `Touch` calls).
  void Forget(Duration now);

  /// Pairs remembered as touching within the gap.
  [[nodiscard]] std::size_t size() const { return last_touch_.size(); }

 private:
  Duration gap_;
  // Car and object (its id) touching: when they last touched.
  std::map<std::pair<int, std::string>, Duration> last_touch_;
};

}  // namespace autodrive::vehicle_sim::internal
