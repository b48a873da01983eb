#pragma once
/// @file
/// The lamps the city's lights report, as the states of SUMO's traffic lights (lights.h says
/// how a head's reports become an aspect and an aspect a link state). Every head's reports are
/// kept; a light is read again only when one of its heads changed (and, for a change to or from
/// dark, until a flash window later: a flash may be starting or ending), or while it runs an
/// all-way stop. A link of an all-way stop is red, green for the vehicle let through
/// (`AllWayStops`); a link held for a lab car (`Hold`) is red. No SUMO here: `Update` says which
/// lights changed, and the co-simulation sets them in SUMO.

#include <cstddef>
#include <string>
#include <vector>

#include "traffic/all_way_stops.h"
#include "traffic/lights.h"
#include "traffic/links.h"

#include "common/ids.h"
#include "common/time.h"

namespace autodrive::traffic {

class LampMapping {
 public:
  /// `lights` must outlive it. `heads`: the highest head id; `flash_window` as
  /// `LightsConfig::flash_window_s`; `step`: SUMO's step (a lamp that may flash is read again
  /// until a flash window and a step after its change). Copyable and movable.
  LampMapping(const LightBinding& lights, std::size_t heads, Duration flash_window, Duration step);

  /// A head's lamp report (`signal_<i>/state`) at control time `now`; a head out of range is
  /// ignored.
  void Report(SignalHeadId head, int lamp, MonoTime now);
  /// The movements SUMO's vehicles must not start now (`LabCarClaims::held`): their links are red.
  void Hold(const std::vector<MovementId>& held, const LinkIndex& links);
  /// Whether any link is held now.
  [[nodiscard]] bool any_held() const { return !held_lights_.empty(); }

  /// Reads the lights due at `now` (telling `stops` which run an all-way stop) and returns the
  /// lights whose state changed, in order; their new states are in `states()`.
  const std::vector<std::size_t>& Update(MonoTime now, AllWayStops& stops);

  /// The link states for SUMO, by light (empty before a light's first `Update`).
  [[nodiscard]] const std::vector<std::string>& states() const { return states_; }
  /// The link states the lamps give, by light: with 's' where an all-way stop runs.
  [[nodiscard]] const std::vector<std::string>& aspects() const { return aspects_; }
  /// By light and link: held for a lab car.
  [[nodiscard]] const std::vector<std::vector<bool>>& held() const { return held_; }

 private:
  const LightBinding* lights_;
  Duration flash_window_;
  Duration step_;
  std::vector<HeadReading> heads_;                        // by head id
  std::vector<std::vector<std::size_t>> lights_of_head_;  // by head id
  std::vector<std::string> states_;                       // by light
  std::vector<std::string> aspects_;                      // by light
  std::vector<MonoTime> recheck_until_;   // by light: a lamp went to or from dark lately
  std::vector<bool> relight_;             // by light: a lamp changed since the last step
  std::vector<std::vector<bool>> held_;   // by light and link
  std::vector<std::size_t> held_lights_;  // the lights with a held link
  std::vector<std::size_t> changed_;      // scratch of `Update`
};

}  // namespace autodrive::traffic
