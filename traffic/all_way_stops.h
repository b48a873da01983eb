#pragma once
/// @file
/// All-way stops, as drivers run them. SUMO's own all-way stop (`s` links, or an allway_stop
/// junction) lets a left turn with a waiting point inside the junction roll through without
/// stopping, and lets vehicles on crossing paths of these small junctions (a 1:14 box at 14x)
/// into the box together. So a light that flashes red or is dark, and every stop-controlled
/// intersection, is arbitrated here: every vehicle stops at the line (its link stays red for it);
/// the one that has stood longest (at least `kStand`) goes, with any others whose movements
/// conflict with no movement granted or occupied; its link turns green until it is in the box,
/// then red again. A vehicle goes only into an exit lane with room for it and its gap. A turn
/// not taken within `kGrant` lapses, and the vehicle goes to the back of the queue.
///
/// The rules run on SUMO's clock (`SumoTime`) over the vehicles SUMO reported after its step;
/// what they ask of SUMO (a vehicle's route, a lane's length, a type's size) goes through
/// `SumoCache`, so that tests drive them with a scripted SUMO.

#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "traffic/lights.h"
#include "traffic/links.h"
#include "traffic/sumo_api.h"
#include "traffic/sumo_cache.h"
#include "traffic/sumo_time.h"

#include "common/time.h"

namespace autodrive::traffic {

class AllWayStops {
 public:
  /// A vehicle stands at the line at least this long before it goes.
  static constexpr Duration kStand = std::chrono::milliseconds(500);
  /// A turn not taken in this long lapses.
  static constexpr Duration kGrant = std::chrono::seconds(5);

  /// A vehicle let through: its link is green for it until it is in the box.
  struct Grant {
    std::string vehicle;
    std::size_t link = 0;
    SumoTime since{};  ///< when it was let through
    double room = 0;   ///< what it takes of its exit lane (SUMO metres)
  };

  /// The lights' aspects and held links, as the lamps and the lab cars leave them this step
  /// (by light; `aspects[i][k]` 's' where link k of light i is an all-way stop; `held[i][k]`:
  /// a lab car is on its way and SUMO's vehicles must not start link k).
  struct Lights {
    const std::vector<std::string>& aspects;
    const std::vector<std::vector<bool>>& held;
  };

  /// `lights` and `links` must outlive it. `scale`: SUMO metres per lab metre; `min_gap`: the
  /// vehicle types' gap (SUMO metres). Copyable and movable (it refers to the two).
  AllWayStops(const LightBinding& lights, const LinkIndex& links, double scale, double min_gap);

  /// Whether light `i` runs an all-way stop now (set as its aspect is read, `LampMapping`).
  void SetRunning(std::size_t light, bool running);
  [[nodiscard]] bool running(std::size_t light) const { return running_[light]; }
  /// Whether any light runs one.
  [[nodiscard]] bool any() const { return running_count_ != 0; }
  /// Whether a vehicle on a lane of `info` is about an all-way stop running now.
  [[nodiscard]] bool Near(const LaneInfo& info) const;

  /// The vehicles let through at light `i`.
  [[nodiscard]] const std::vector<Grant>& grants(std::size_t light) const { return grants_[light]; }
  /// Whether `vehicle` is let through at light `i`.
  [[nodiscard]] bool Granted(std::size_t light, const std::string& vehicle) const;

  /// One arbitration after SUMO's step at `now`: `vehicles` as SUMO reported them (lane
  /// positions read for those on lanes `Near` an all-way stop, and for the lab's cars),
  /// `lab_ids` every SUMO id a lab car had (they go when their drivers decide; what they need is
  /// held in `lights.held`). Asks `sumo` for the route of a vehicle that may go.
  void Arbitrate(SumoTime now, const std::vector<SumoVehicleState>& vehicles,
                 const std::unordered_set<std::string>& lab_ids, const Lights& lights,
                 LaneLookup& lanes, SumoCache& sumo);

  /// Vehicles let through since the start.
  [[nodiscard]] std::int64_t granted_count() const { return granted_count_; }
  /// Of them, those that did not go in time.
  [[nodiscard]] std::int64_t lapsed_count() const { return lapsed_count_; }

 private:
  struct Waiting {
    SumoTime since;
    std::string vehicle;
    const LinkIndex::StopLane* lane;
    std::string type;
  };
  // Room at the start of each lane (SUMO metres up to the last vehicle's back), less what the
  // vehicles in a box or let through on their way into it take.
  class Room;
  // Reads where the vehicles are: occupied links, room, who waits at a line.
  void Survey(SumoTime now, const std::vector<SumoVehicleState>& vehicles,
              const std::unordered_set<std::string>& lab_ids, LaneLookup& lanes, SumoCache& sumo,
              Room& room);
  // Ends the grants of vehicles gone into the box (or gone), and those that lapsed (returned).
  std::vector<std::string> EndGrants(SumoTime now);
  // Lets the waiting vehicles go that may, longest standing first.
  void LetThrough(SumoTime now, const Lights& lights, SumoCache& sumo, Room& room);

  const LightBinding* lights_;
  const LinkIndex* links_;
  double scale_ = 14.0;
  double min_gap_ = 0.7;
  std::vector<bool> running_;  // by light
  std::size_t running_count_ = 0;
  std::vector<std::vector<bool>> occupied_;  // by light and link: a vehicle in its lanes
  std::vector<std::vector<Grant>> grants_;   // by light
  std::unordered_map<std::string, SumoTime> standing_since_;  // vehicle, at a stop line
  // Scratch of one arbitration.
  std::vector<Waiting> waiting_;
  std::unordered_map<std::string, std::string> lane_of_;
  std::int64_t granted_count_ = 0;
  std::int64_t lapsed_count_ = 0;
};

}  // namespace autodrive::traffic
