#pragma once
/// @file
/// The city model the SCM runs: the city file checked against its map and the signal safety
/// rules (docs/scm.md, "Safety"), with every duration in lab time. Immutable once
/// built; controllers and the conflict monitor borrow it.

#include <cstddef>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/aspect.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/districts.h"
#include "maps/map.h"
#include "scm/core/city_config.h"

namespace autodrive::scm {

/// Timing of one signal group, lab time.
struct GroupTiming {
  Duration min_green{0};
  Duration max_green{0};
  Duration yellow{0};
  Duration red_clearance{0};
};

/// A signal group: movements that always show the same aspect, and the heads that show it.
struct SignalGroup {
  SignalGroupId id{0};
  std::string name;
  std::vector<MovementId> movements;
  std::vector<SignalHeadId> heads;
  GroupTiming timing;
  Aspect flash_aspect = Aspect::kFlashingRed;
};

enum class PlanType { kFixed, kActuated, kFlash, kDark };
/// When an actuated controller settles the phase it runs next (docs/controller.md, "Next phase
/// decision"): when the green ends, or at every step of the yellow and red clearance, the
/// nearest called phase then (SUMO 1.15's NEMA controller).
enum class NextPhaseDecision { kEndOfGreen, kEndOfClearance };
/// How an actuated green rests with no conflicting call: as NTCIP times it (its passage runs
/// whatever the other calls do), or as SUMO 1.15's NEMA controller does (docs/controller.md,
/// "Green rest").
enum class GreenRest { kNtcip, kSumo };
/// "fixed", "actuated", "flash", "dark".
[[nodiscard]] std::string_view ToString(PlanType type);

/// A phase: groups (indices into `IntersectionModel::groups`) green together.
struct Phase {
  std::vector<std::size_t> groups;
  Duration green{0};  ///< fixed-time green
};

/// A detector zone on one ingress lane: distances upstream of the stop line.
struct Detector {
  std::size_t group = 0;  ///< index of the group it calls
  LaneId lane{0};
  double from_stop_line_m = 0.0;
  double to_stop_line_m = 0.0;
};

/// A signal plan in lab time.
struct Plan {
  std::string name;
  PlanType type = PlanType::kFixed;
  Duration offset{0};
  std::vector<Phase> phases;
  Duration extension{0};
  std::vector<Detector> detectors;
  /// Fixed-time cycle: the phases' greens and clearances.
  Duration cycle{0};
  /// Start of each phase's green within the cycle.
  std::vector<Duration> phase_starts;
};

/// Sets `plan`'s phase starts and cycle from its greens and `groups`' clearances: each phase
/// change adds the longest yellow and red clearance of the groups it ends.
void SetPlanCycle(const std::vector<SignalGroup>& groups, Plan& plan);

/// From `minute_of_day` on, `plan` (an index into `IntersectionModel::plans`).
struct ScheduleEntry {
  int minute_of_day = 0;
  std::size_t plan = 0;
};

/// Priority and pre-emption parameters, lab time (docs/controller.md, "Pre-emption"; the NTCIP
/// 1202 preempt object each pre-emption field is).
struct PriorityParams {
  bool enabled = true;
  Duration max_extension{0};
  Duration max_preemption{0};        ///< preemptMaximumPresence
  Duration preempt_delay{0};         ///< preemptDelay
  Duration preempt_min_duration{0};  ///< preemptMinimumDuration
  /// preemptMinimumGreen; none: each green's min green.
  std::optional<Duration> preempt_min_green;
  Duration preempt_track_green{0};  ///< preemptTrackGreen; zero: no track clearance
  /// The groups (indexes) of the track clearance; preemptTrackPhase is the phase of the running
  /// plan that drives them all (every plan with phases has one, checked at load).
  std::vector<std::size_t> preempt_track_groups;
  Duration preempt_dwell_green{0};  ///< preemptDwellGreen (the minimum dwell)

  /// Whether a track clearance comes before the dwell.
  [[nodiscard]] bool track() const {
    return preempt_track_green > Duration{0} && !preempt_track_groups.empty();
  }
};

/// One signalised intersection, ready to run.
struct IntersectionModel {
  IntersectionId id{0};
  std::string name;
  std::vector<SignalGroup> groups;
  /// conflicts[a][b]: groups a and b (indices) may never show green or yellow together.
  std::vector<std::vector<bool>> conflicts;
  /// intergreens[a][b]: the least time from the end of conflicting group a's green to the start
  /// of group b's, computed from the map (scm/core/intergreen.h); zero where a and b do not
  /// conflict. Each group's yellow plus red clearance is at or above every entry of its row
  /// (checked at load), and the conflict monitor holds every green to it.
  std::vector<std::vector<Duration>> intergreens;
  std::vector<Plan> plans;
  std::vector<ScheduleEntry> schedule;  ///< sorted by minute; never empty
  PriorityParams priority;
  NextPhaseDecision next_phase_decision = NextPhaseDecision::kEndOfGreen;
  GreenRest green_rest = GreenRest::kNtcip;
  Duration startup_flash{0};
  Duration startup_all_red{0};

  /// The index of the group with id `id`, or nothing.
  [[nodiscard]] std::optional<std::size_t> GroupIndex(SignalGroupId id) const;
  /// The index of the plan called `name`, or nothing.
  [[nodiscard]] std::optional<std::size_t> PlanIndex(std::string_view name) const;
  /// The index of the group that controls `movement`, or nothing.
  [[nodiscard]] std::optional<std::size_t> GroupOfMovement(MovementId movement) const;
  /// The plan the schedule asks for at `minute_of_day` (0..1439).
  [[nodiscard]] std::size_t ScheduledPlan(int minute_of_day) const;
};

/// The whole city. Move-only in practice (it holds the map); copyable but large.
struct City {
  CityConfig config;
  std::string config_text;            ///< the file's text as loaded
  std::filesystem::path config_path;  ///< where it came from (may be empty)
  maps::Map map;
  std::vector<IntersectionModel> intersections;  ///< the signalised ones, in map order
  SafetyConfig floors_config;                    ///< as configured (for messages)
  GroupTiming floors;  ///< safety floors in lab time (min_green, yellow, red_clearance)
  Duration device_timeout{0};
  Duration device_mismatch{0};
  Duration fleet_staleness{0};
  /// The city's districts, as configured (empty: the whole city is one).
  maps::Districts districts;
  /// The district this city is narrowed to (`NarrowToDistrict`), or empty for the whole city.
  std::string district;

  /// The intersection with id `id`, or null.
  [[nodiscard]] const IntersectionModel* Find(IntersectionId id) const;
  /// The intersection named `name` (or with the decimal id `name`), or null.
  [[nodiscard]] const IntersectionModel* Find(std::string_view name) const;
};

/// Narrows `city` to its district `name`: it keeps only that district's signalised
/// intersections (an SCM started with `--district` runs those and publishes only them in MAP and
/// SPaT). Throws `InputError` naming the city's districts when it has no district `name`.
void NarrowToDistrict(City& city, std::string_view name);

/// The DDS domain of district `name` of the city file `path` (read, not checked: the SCM checks
/// the whole city once it runs). `requested`: a domain the command line asked for, which must
/// then be the district's. Throws `InputError` when the file has no such district or the
/// domains differ, `ConfigError` when the file does not parse.
[[nodiscard]] std::uint32_t DistrictDomain(const std::filesystem::path& path, std::string_view name,
                                           std::optional<std::uint32_t> requested);

/// The hard minimums of the safety floors, in lab time: no city file may go below them,
/// whatever its `safety` section and `time_scale` say (docs/scm.md, "Safety floors").
inline constexpr GroupTiming kHardMinimums{
    std::chrono::milliseconds(1000),  // min_green
    Duration{0},                      // max_green: no floor
    std::chrono::milliseconds(1000),  // yellow
    std::chrono::milliseconds(500),   // red_clearance
};

/// Where a city's map comes from: a relative path is resolved against `base_dir`; with a
/// `root`, the resolved file must lie under it (for text that came over the network).
struct MapResolution {
  std::filesystem::path base_dir;
  std::optional<std::filesystem::path> root;
};

/// Checks `config` against `map` and the safety rules and builds the model. Throws
/// `ConfigError` "SOURCE: KEYPATH (NAME): what; rule: RULE" naming the intersection, the groups
/// and the rule broken.
[[nodiscard]] City BuildCity(const CityConfig& config, maps::Map map, const std::string& source);

/// Loads a city from YAML text; the map path is resolved against `base_dir`. `source` names the
/// text in messages. Throws `ConfigError` / `InputError`.
[[nodiscard]] City LoadCityString(const std::string& yaml, const std::string& source,
                                  const std::filesystem::path& base_dir);
/// Loads a city from YAML text with `resolution`'s rules for the map. Text with a NUL byte is
/// refused (ConfigError naming the offset).
[[nodiscard]] City LoadCityString(const std::string& yaml, const std::string& source,
                                  const MapResolution& resolution);

/// Loads a city file.
[[nodiscard]] City LoadCity(const std::filesystem::path& path);

/// Lab duration of a configured duration.
[[nodiscard]] Duration Scaled(nanoseconds configured, double time_scale);

}  // namespace autodrive::scm
