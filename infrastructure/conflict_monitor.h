#pragma once
/// @file
/// The independent conflict monitor (a malfunction management unit, MMU): watches the lamps
/// the heads of one intersection actually show and latches the intersection into flashing red
/// when two heads whose traffic conflicts both show green or yellow. Which heads conflict is
/// derived from the map's geometry, independently of the SCM's signal groups and plans.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "infrastructure/lamps.h"
#include "maps/map.h"

namespace autodrive::infrastructure {

/// Two heads of an intersection whose traffic conflicts, with the movement pairs that make them
/// conflict (each pair: a movement from `a`'s approach, a conflicting one from `b`'s).
struct HeadConflict {
  SignalHeadId a{0};  ///< the smaller id
  SignalHeadId b{0};
  std::vector<std::pair<MovementId, MovementId>> movements;  ///< sorted
  bool operator==(const HeadConflict&) const = default;
};

/// Every pair of signal heads of intersection `intersection` that conflict, ordered by (a, b).
/// A head faces one approach (`SignalHead::approach`) and governs the movements coming from it;
/// two heads conflict when any movement from one's approach conflicts with any movement from
/// the other's (`maps::Map::Conflict`, from geometry: crossing, merging or passing too close).
/// Throws `InputError` when the map has no such intersection.
[[nodiscard]] std::vector<HeadConflict> ComputeHeadConflicts(const maps::Map& map,
                                                             IntersectionId intersection);

/// Why a monitor latched.
struct MonitorLatch {
  SignalHeadId a{0};  ///< one head of the conflicting pair (the smaller id)
  SignalHeadId b{0};  ///< the other
  Lamps lamps_a;      ///< what `a` showed when the monitor latched
  Lamps lamps_b;      ///< what `b` showed
  MonoTime since{};   ///< when both started showing green or yellow
  MonoTime at{};      ///< when the monitor latched
  /// "signal_1 showed green and signal_2 showed yellow together for 0.30 s; their movements
  /// conflict (r2c2:E>W:0>0 with r2c2:N>S:0>0)".
  std::string message;
};

/// The monitor of one intersection. Feed it the lamps of the hosted heads every tick
/// (`Observe`), then `Update`. A head "shows go" while its green or yellow lamp is lit (as a
/// NEMA MMU senses its field inputs: a flashing yellow counts while lit); when two conflicting
/// heads both show go without a break for at least the persistence, the monitor latches, and
/// stays latched until `Reset` (an operator's). Heads whose lamps are unknown (offline) are not
/// counted. Not thread-safe; copyable.
class ConflictMonitor {
 public:
  /// Monitors the heads `hosted` (all of `intersection`'s heads when empty) of `intersection`
  /// of `map`. `persistence` > 0. Throws `InputError` when a hosted head is not one of the
  /// intersection's.
  ConflictMonitor(const maps::Map& map, IntersectionId intersection,
                  const std::vector<SignalHeadId>& hosted, Duration persistence);

  /// The lamps `head` shows at `now`; nothing when unknown. Heads not monitored are ignored.
  void Observe(SignalHeadId head, const std::optional<Lamps>& lamps, MonoTime now);
  /// Checks the pairs at `now`. Returns the latch when it latches now (once).
  std::optional<MonitorLatch> Update(MonoTime now);
  /// Clears the latch; returns whether it was latched.
  bool Reset();
  /// The time base restarted (a new session of the simulated clock): forgets since when each
  /// head has shown go, so that the persistence is counted again on the new timeline from the
  /// next `Observe`. A latch stays latched.
  void RestartTimers();
  /// The instant at which the monitor latches if the lamps stay as they are: the earliest
  /// instant at which a conflicting pair that both show go reaches the persistence. Nothing
  /// while latched or while no conflicting pair shows go.
  [[nodiscard]] std::optional<MonoTime> NextLatch() const;

  /// True from the latch until `Reset`.
  [[nodiscard]] bool latched() const { return latch_.has_value(); }
  /// Why it latched, while latched.
  [[nodiscard]] const std::optional<MonitorLatch>& latch() const { return latch_; }
  /// The intersection it watches.
  [[nodiscard]] IntersectionId intersection() const { return intersection_; }
  /// The intersection's name in the map.
  [[nodiscard]] const std::string& intersection_name() const { return name_; }
  /// "mmu_<intersection name>", its device id in DeviceStatus.
  [[nodiscard]] std::string device_id() const { return "mmu_" + name_; }
  /// The monitored heads, in id order.
  [[nodiscard]] const std::vector<SignalHeadId>& heads() const { return heads_; }
  /// The conflicting pairs among the monitored heads.
  [[nodiscard]] const std::vector<HeadConflict>& conflicts() const { return conflicts_; }

 private:
  struct HeadState {
    std::optional<Lamps> lamps;
    std::optional<MonoTime> go_since;  // showing green or yellow without a break since
  };
  HeadState* Find(SignalHeadId head);

  IntersectionId intersection_;
  std::string name_;
  std::vector<SignalHeadId> heads_;
  std::vector<HeadConflict> conflicts_;
  std::vector<std::string> movement_names_;  // by movement id - 1, for messages
  Duration persistence_;
  std::vector<HeadState> states_;  // parallel to heads_
  std::optional<MonitorLatch> latch_;
};

}  // namespace autodrive::infrastructure
