#pragma once
/// @file
/// The parts `BuildCity` builds one intersection from, each a pure rule over the city file and
/// the map: its signal groups, their conflict matrix, the heads that show them, its plans and
/// its schedule. Each throws `ConfigError` "SOURCE: KEYPATH (NAME): what; rule: RULE" on the
/// first rule the configuration breaks, in the order the file is read. Not part of the SCM's
/// API: `scm/core/city.h` is.

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"
#include "scm/core/city.h"
#include "scm/core/city_config.h"

namespace autodrive::scm::internal {

/// Collects the context of an error message: "SOURCE: intersections[1] (centre): ...".
/// Copyable value.
class Where {
 public:
  explicit Where(std::string source);
  /// This context followed by `part` (": part" after the source, ".part" after that).
  [[nodiscard]] Where Then(const std::string& part) const;
  /// Throws `ConfigError` "CONTEXT: what".
  [[noreturn]] void Fail(const std::string& what) const;

 private:
  std::string text_;
  bool first_ = true;
};

/// One intersection of the map, as the builder checks a configuration against it. Borrows both;
/// they must outlive it.
struct MapSite {
  const maps::Map& map;
  const maps::Intersection& x;

  /// The side of the approach movement `m` comes from (`m` must be one of `x`'s movements).
  [[nodiscard]] maps::Side SideOf(MovementId m) const;
  /// Whether `x` has an approach on `side`.
  [[nodiscard]] bool HasApproach(maps::Side side) const;
};

/// "ID (NAME)", the way messages name a group.
[[nodiscard]] std::string GroupLabel(const SignalGroup& g);

/// The index of the group with id `id` in `groups`; fails "unknown signal group ID" at `where`.
[[nodiscard]] std::size_t GroupById(const std::vector<SignalGroup>& groups, std::uint32_t id,
                                    const Where& where);

/// What every group's timing must reach: the safety floors (lab time) and the vehicles its red
/// clearance must let through.
struct GroupFloors {
  GroupTiming timing;
  std::vector<ClearingVehicleConfig> clearing_vehicles;
};

/// An intersection's signal groups, and which of them controls each of its movements.
struct Groups {
  std::vector<SignalGroup> groups;  ///< without heads (`AssignHeads` adds them)
  std::map<MovementId, std::size_t> group_of;
};

/// Builds the groups of `cfg` at `site`, in lab time at `time_scale`. Rules: ids and names are
/// unique, a group controls at least one movement, a movement belongs to one group and every
/// movement to some group, conflicting movements are never in one group, and each group's
/// timing is at or above the safety `floors`, its red clearance at or above the ITE figure
/// (W + L) / V for the floors' clearing vehicles (the figure where none is configured).
[[nodiscard]] Groups BuildGroups(const IntersectionConfig& cfg, const MapSite& site,
                                 const GroupFloors& floors, double time_scale, const Where& where);

/// conflicts[a][b]: groups a and b (indices) may never show green or yellow together.
using ConflictMatrix = std::vector<std::vector<bool>>;

/// The conflict matrix of `groups`: derived from the map's geometry, replaced by `conflicts`
/// (which may not drop a geometric conflict) and extended by `extra_conflicts`.
[[nodiscard]] ConflictMatrix BuildConflicts(const IntersectionConfig& cfg, const MapSite& site,
                                            const Groups& groups, const Where& where);

/// Adds to each group the heads that show it: as `cfg.heads` says, else the one group of the
/// head's approach. Rules: a head of the intersection, listed once, shows a group of its own
/// approach; an approach with several groups needs its heads listed.
void AssignHeads(const IntersectionConfig& cfg, const MapSite& site, Groups& groups,
                 const Where& where);

/// One plan of `x` (whose groups and conflicts are built), in lab time at `time_scale`: its
/// phases, its fixed-time cycle and its detectors. Rules: conflicting groups never share a
/// phase, greens within the groups' min and max greens, every group served, detectors only in
/// an actuated plan and on an approach their group controls.
[[nodiscard]] Plan BuildPlan(const PlanConfig& pc, const IntersectionModel& x, const MapSite& site,
                             double time_scale, const Where& where);

/// The plans of `cfg` (`BuildPlan` each); names unique, not "" or "auto", at least one.
[[nodiscard]] std::vector<Plan> BuildPlans(const IntersectionConfig& cfg,
                                           const IntersectionModel& x, const MapSite& site,
                                           double time_scale, const Where& where);

/// Checks the crosswalks of `cfg` at `site` against `x` (its groups built, timing in lab time at
/// `time_scale`) and the MUTCD (scm/core/pedestrian_timing.h) at the lab's scale
/// (`maps::kSumoScale`; docs/controller.md, "Pedestrians"). Rules: one crosswalk per leg of the
/// intersection, as long as the leg's traveled way; the groups it crosses drive across its leg
/// and include every group with a movement from the leg or straight into it (only turns into
/// the leg may cross it permissively); walk, ped clear and walk + ped clear at or above the
/// MUTCD minimums for its full-scale length and push-button setback; every other group (those
/// parallel to it) with a yellow + red clearance of at least the 3 s buffer interval. Times are
/// compared as configured (full-scale seconds), before `time_scale`.
void CheckCrosswalks(const IntersectionConfig& cfg, const IntersectionModel& x, const MapSite& site,
                     double time_scale, const Where& where);

/// "HH:MM" as minutes of the day; fails at `where` on anything else.
[[nodiscard]] int ParseMinuteOfDay(const std::string& text, const Where& where);

/// The schedule of `cfg` over the plans of `x`, sorted by minute; with no entry, plan 0 all day.
/// Rules: known plans, valid times, no minute twice.
[[nodiscard]] std::vector<ScheduleEntry> BuildSchedule(const IntersectionConfig& cfg,
                                                       const IntersectionModel& x,
                                                       const Where& where);

}  // namespace autodrive::scm::internal
