#pragma once
/// @file
/// The city configuration file (`config/cities/*.yaml`) as plain structs, loaded strictly by
/// `common/config.h`. These structs say what the file holds; `scm/core/city.h` checks them against
/// the map and the safety rules and builds the model the controllers run. The format is
/// documented with an example in docs/scm.md.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/config.h"
#include "maps/districts.h"

namespace autodrive::scm {

using std::chrono::nanoseconds;

/// Timing of signal groups, in configured seconds (multiplied by the city's `time_scale` to get
/// lab seconds).
struct TimingConfig {
  nanoseconds min_green_s = std::chrono::seconds(5);
  nanoseconds max_green_s = std::chrono::seconds(20);
  nanoseconds yellow_s = std::chrono::seconds(3);
  /// Absent: the ITE red clearance (W + L) / V of each group, from the map's movement lengths and
  /// the city's `safety.clearing_vehicles`. Present: at least that (refused below it).
  std::optional<nanoseconds> red_clearance_s;

  template <typename Archive>
  void Serialize(Archive& a) {
    const config::Range<nanoseconds> range{nanoseconds(0), std::chrono::hours(1)};
    a.Optional("min_green_s", min_green_s, range);
    a.Optional("max_green_s", max_green_s, range);
    a.Optional("yellow_s", yellow_s, range);
    a.Optional("red_clearance_s", red_clearance_s, range);
  }
  void Validate() const;
  bool operator==(const TimingConfig&) const = default;
};

/// Per-group overrides of the intersection's timing; absent keys keep the intersection's.
struct GroupTimingConfig {
  std::optional<nanoseconds> min_green_s;
  std::optional<nanoseconds> max_green_s;
  std::optional<nanoseconds> yellow_s;
  std::optional<nanoseconds> red_clearance_s;

  template <typename Archive>
  void Serialize(Archive& a) {
    const config::Range<nanoseconds> range{nanoseconds(0), std::chrono::hours(1)};
    a.Optional("min_green_s", min_green_s, range);
    a.Optional("max_green_s", max_green_s, range);
    a.Optional("yellow_s", yellow_s, range);
    a.Optional("red_clearance_s", red_clearance_s, range);
  }
  bool operator==(const GroupTimingConfig&) const = default;
};

/// A signal group: a set of the map's movements that always show the same aspect.
struct SignalGroupConfig {
  std::uint32_t id = 0;  ///< 1..255, unique in the intersection
  std::string name;
  /// Every movement coming from these approaches ("east", "north", "west", "south").
  std::vector<std::string> approaches;
  /// Further movements by their map name, e.g. "r2c2:S>W:0>0".
  std::vector<std::string> movements;
  GroupTimingConfig timing;
  /// What the group shows in flash: "red" (flashing red, stop then proceed) or "yellow"
  /// (flashing yellow, caution) for a main road.
  std::string flash = "red";

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("id", id, config::Range<std::uint32_t>{1, 255});
    a.Required("name", name);
    a.Optional("approaches", approaches, config::OneOf{{"east", "north", "west", "south"}});
    a.Optional("movements", movements);
    a.Optional("timing", timing);
    a.Optional("flash", flash, config::OneOf{{"red", "yellow"}});
  }
  bool operator==(const SignalGroupConfig&) const = default;
};

/// Which signal group a traffic light head shows.
struct HeadConfig {
  std::uint32_t head = 0;   ///< the map's signal head id (`signal_<head>`)
  std::uint32_t group = 0;  ///< the group it shows

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("head", head, config::Range<std::uint32_t>{1, 1000000});
    a.Required("group", group, config::Range<std::uint32_t>{1, 255});
  }
  bool operator==(const HeadConfig&) const = default;
};

/// One phase of a plan: groups green together.
struct PhaseConfig {
  std::vector<std::uint32_t> groups;
  /// Green time of a fixed-time phase (configured seconds); actuated plans use it as the
  /// fixed-time fallback and default to the groups' max green.
  std::optional<nanoseconds> green_s;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("groups", groups, config::Range<std::uint32_t>{1, 255});
    a.Optional("green_s", green_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::hours(1)});
  }
  bool operator==(const PhaseConfig&) const = default;
};

/// A detector zone: a stretch of the ingress lanes of an approach just before the stop line.
struct DetectorConfig {
  std::uint32_t group = 0;  ///< the group it calls
  std::string approach;     ///< its ingress lanes ("east", ...)
  double setback_m = 0.0;   ///< distance of the zone's downstream edge before the stop line
  double length_m = 0.6;    ///< length of the zone upstream from there

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("group", group, config::Range<std::uint32_t>{1, 255});
    a.Required("approach", approach, config::OneOf{{"east", "north", "west", "south"}});
    a.Optional("setback_m", setback_m, config::Range{0.0, 10.0});
    a.Optional("length_m", length_m, config::Range{0.01, 10.0});
  }
  bool operator==(const DetectorConfig&) const = default;
};

/// A signal plan.
struct PlanConfig {
  std::string name;
  /// fixed: phases with green times and an offset; actuated: phases extended by detector calls;
  /// flash; dark.
  std::string type = "fixed";
  nanoseconds offset_s{0};  ///< fixed: where phase 1's green starts in the cycle, from midnight
  std::vector<PhaseConfig> phases;
  nanoseconds extension_s = std::chrono::seconds(2);  ///< actuated: gap time
  std::vector<DetectorConfig> detectors;              ///< actuated

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("type", type, config::OneOf{{"fixed", "actuated", "flash", "dark"}});
    a.Optional("offset_s", offset_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::hours(1)});
    a.Optional("phases", phases);
    a.Optional("extension_s", extension_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(100), std::chrono::minutes(1)});
    a.Optional("detectors", detectors);
  }
  bool operator==(const PlanConfig&) const = default;
};

/// From a time of day on, run a plan.
struct ScheduleEntryConfig {
  std::string at;  ///< "HH:MM", local time of the SCM host (TZ)
  std::string plan;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("at", at);
    a.Required("plan", plan);
  }
  bool operator==(const ScheduleEntryConfig&) const = default;
};

/// V2I priority and pre-emption at one intersection. The pre-emption keys are NTCIP 1202's
/// preempt table (asc.6.2.1) for the one preempt V2I emergency requests call, in configured
/// seconds (docs/controller.md, "Pre-emption").
struct PriorityConfig {
  bool enabled = true;
  /// Longest a priority request may extend a green beyond its max green (configured s).
  nanoseconds max_extension_s = std::chrono::seconds(10);
  /// Longest a pre-emption input may stay on before it is released (preemptMaximumPresence).
  nanoseconds max_preemption_s = std::chrono::seconds(60);
  /// From the call input on to the start of entry (preemptDelay).
  nanoseconds preempt_delay_s{0};
  /// Least time from entry to the end of the dwell (preemptMinimumDuration).
  nanoseconds preempt_min_duration_s{0};
  /// A green in service at entry is not ended before the lesser of its min green and this
  /// (preemptMinimumGreen). Absent: its min green. Never below a group's min green here (the
  /// conflict monitor holds every green to it).
  std::optional<nanoseconds> preempt_min_green_s;
  /// Green of the track groups before the dwell (preemptTrackGreen); 0: no track clearance.
  nanoseconds preempt_track_green_s{0};
  /// The groups green for the track clearance (preemptTrackPhase: the running plan's phase that
  /// drives them all).
  std::vector<std::uint32_t> preempt_track_groups;
  /// Least green of the dwell phase (preemptDwellGreen, the minimum dwell).
  nanoseconds preempt_dwell_green_s = std::chrono::seconds(5);
  /// Where the pre-emption exits (preemptExitPhase): `next`, the phase after the dwell phase in
  /// the running plan's sequence.
  std::string preempt_exit = "next";

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("enabled", enabled);
    a.Optional("max_extension_s", max_extension_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::minutes(10)});
    a.Optional("max_preemption_s", max_preemption_s,
               config::Range<nanoseconds>{std::chrono::seconds(1), std::chrono::hours(1)});
    a.Optional("preempt_delay_s", preempt_delay_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::seconds(600)});
    a.Optional("preempt_min_duration_s", preempt_min_duration_s,
               config::Range<nanoseconds>{nanoseconds(0), std::chrono::hours(1)});
    const config::Range<nanoseconds> to_255{nanoseconds(0), std::chrono::seconds(255)};
    a.Optional("preempt_min_green_s", preempt_min_green_s, to_255);
    a.Optional("preempt_track_green_s", preempt_track_green_s, to_255);
    a.Optional("preempt_track_groups", preempt_track_groups, config::Range<std::uint32_t>{1, 255});
    a.Optional("preempt_dwell_green_s", preempt_dwell_green_s,
               config::Range<nanoseconds>{std::chrono::seconds(1), std::chrono::seconds(255)});
    a.Optional("preempt_exit", preempt_exit, config::OneOf{{"next"}});
  }
  bool operator==(const PriorityConfig&) const = default;
};

/// A marked crosswalk across one leg of an intersection and its pedestrian timing, checked at
/// load against the MUTCD at the lab's scale (docs/controller.md, "Pedestrians").
struct CrosswalkConfig {
  std::string leg;        ///< the leg it crosses: "east", "north", "west", "south"
  double length_m = 0.0;  ///< lab metres, from the kerb to the far side of the traveled way
  /// Lab metres from the push button to the kerb. Absent: no push button (the MUTCD's 6 ft).
  std::optional<double> button_setback_m;
  /// The groups whose vehicles cross it (never green during its walk and ped clear). With
  /// neither `groups` nor `movements`: every group with a movement from or into its leg.
  std::vector<std::uint32_t> groups;
  /// Further movements by map name that cross it: their groups are added to `groups`.
  std::vector<std::string> movements;
  /// Steady walk (NTCIP phaseWalk), configured seconds: the MUTCD's full-scale seconds.
  nanoseconds walk_s{0};
  nanoseconds ped_clear_s{0};  ///< flashing don't walk (NTCIP phasePedestrianClear), as walk_s

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("leg", leg, config::OneOf{{"east", "north", "west", "south"}});
    a.Required("length_m", length_m, config::Range{0.01, 10.0});
    a.Optional("button_setback_m", button_setback_m, config::Range{0.0, 10.0});
    a.Optional("groups", groups, config::Range<std::uint32_t>{1, 255});
    a.Optional("movements", movements);
    const config::Range<nanoseconds> range{nanoseconds(0), std::chrono::minutes(5)};
    a.Required("walk_s", walk_s, range);
    a.Required("ped_clear_s", ped_clear_s, range);
  }
  bool operator==(const CrosswalkConfig&) const = default;
};

/// A signalised intersection of the map.
struct IntersectionConfig {
  std::string name;  ///< the map's intersection name
  TimingConfig timing;
  std::vector<SignalGroupConfig> groups;
  /// The full conflict matrix as pairs of group ids. Absent: derived from the map. Present: it
  /// must hold every pair the map's geometry makes conflict (it may add pairs, never remove).
  std::optional<std::vector<std::vector<std::uint32_t>>> conflicts;
  /// Conflicts added to the derived ones.
  std::vector<std::vector<std::uint32_t>> extra_conflicts;
  /// Which group each head shows. Heads not listed show the group of their approach.
  std::vector<HeadConfig> heads;
  std::vector<PlanConfig> plans;
  /// Plans by time of day; empty: the first plan all day.
  std::vector<ScheduleEntryConfig> schedule;
  PriorityConfig priority;
  /// end_of_green: an actuated green's successor is chosen when the green ends;
  /// end_of_clearance: chosen again at every step of the clearance (SUMO's NEMA controller).
  std::string next_phase_decision = "end_of_green";
  /// ntcip: an actuated green's passage runs whatever the other calls do; sumo: as SUMO 1.15's
  /// NEMA controller rests in green (docs/controller.md, "Green rest").
  std::string green_rest = "ntcip";
  /// Marked crosswalks with pedestrian signals, at most one per leg.
  std::vector<CrosswalkConfig> crosswalks;
  /// Pedestrian volumes do not need the MUTCD's 7 s walk: walks as short as 4 s are allowed.
  bool low_pedestrian_volume = false;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("timing", timing);
    a.Required("groups", groups);
    a.Optional("conflicts", conflicts);
    a.Optional("extra_conflicts", extra_conflicts);
    a.Optional("heads", heads);
    a.Required("plans", plans);
    a.Optional("schedule", schedule);
    a.Optional("priority", priority);
    a.Optional("next_phase_decision", next_phase_decision,
               config::OneOf{{"end_of_green", "end_of_clearance"}});
    a.Optional("green_rest", green_rest, config::OneOf{{"ntcip", "sumo"}});
    a.Optional("crosswalks", crosswalks);
    a.Optional("low_pedestrian_volume", low_pedestrian_volume);
  }
  bool operator==(const IntersectionConfig&) const = default;
};

/// A vehicle that must be able to clear an intersection it entered on the last instant of
/// yellow before any conflicting green (the ITE red clearance (W + L) / V, lab units).
struct ClearingVehicleConfig {
  std::string name;
  double length_m = 0.318;  ///< L: its length (Nigel's)
  double speed_mps = 0.2;   ///< V: its speed through the box (Nigel's typical; 0.26 at the most)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("length_m", length_m, config::Range<double>{0.01, 20.0});
    a.Required("speed_mps", speed_mps, config::Range<double>{0.01, 50.0});
  }
  bool operator==(const ClearingVehicleConfig&) const = default;
};

/// The safety floors every timing must respect (configured seconds, scaled like the rest).
struct SafetyConfig {
  nanoseconds min_yellow_s = std::chrono::seconds(3);
  nanoseconds min_red_clearance_s = std::chrono::seconds(1);
  nanoseconds min_green_s = std::chrono::seconds(4);
  /// The slowest, longest vehicles that cross the city's intersections: every group's red
  /// clearance covers each of them (docs/scm.md, "Clearances"). Default: a Nigel at 0.2 m/s.
  std::vector<ClearingVehicleConfig> clearing_vehicles{{"nigel", 0.318, 0.2}};
  /// The intergreen matrix's entering speed: the fastest a vehicle crosses its stop line as its
  /// green starts (m/s). Default: a Nigel's top speed.
  double entering_speed_mps = 0.26;
  /// The intergreen matrix's t_cross: how long after its green ends a vehicle may still cross
  /// its stop line (lab seconds). Default 0: the lab's cars stop once their green ends.
  double crossing_time_s = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    const config::Range<nanoseconds> range{std::chrono::milliseconds(100), std::chrono::minutes(1)};
    a.Optional("min_yellow_s", min_yellow_s, range);
    a.Optional("min_red_clearance_s", min_red_clearance_s, range);
    a.Optional("min_green_s", min_green_s, range);
    a.Optional("clearing_vehicles", clearing_vehicles);
    a.Optional("entering_speed_mps", entering_speed_mps, config::Range<double>{0.01, 50.0});
    a.Optional("crossing_time_s", crossing_time_s, config::Range<double>{0.0, 60.0});
  }
  bool operator==(const SafetyConfig&) const = default;
};

/// The start-up sequence: flash, then all red, then the plan (configured seconds).
struct StartUpConfig {
  nanoseconds flash_s = std::chrono::seconds(3);
  /// Absent: each intersection's longest red clearance. Present: at least that.
  std::optional<nanoseconds> all_red_s;

  template <typename Archive>
  void Serialize(Archive& a) {
    const config::Range<nanoseconds> range{nanoseconds(0), std::chrono::minutes(10)};
    a.Optional("flash_s", flash_s, range);
    a.Optional("all_red_s", all_red_s, range);
  }
  bool operator==(const StartUpConfig&) const = default;
};

/// The vehicles the SCM tracks and how.
struct FleetConfig {
  /// Vehicles whose devkit `ips` topic feeds the fleet state, e.g. "nigel_1".
  std::vector<std::string> vehicles;
  /// Observations older than this are dropped (lab seconds, not scaled).
  nanoseconds staleness_s = std::chrono::seconds(1);
  /// The Eye's poses (`/autodrive/eye/fleet`, with headings) feed the fleet state too, and are
  /// preferred to the `ips` topics' positions.
  bool eye = false;
  /// SUMO's background vehicles (`/autodrive/scm/traffic`, autodrive-traffic) count on the
  /// detectors and approaches as lab cars do; they are not part of the published fleet state.
  bool traffic = true;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("vehicles", vehicles);
    a.Optional("eye", eye);
    a.Optional("traffic", traffic);
    a.Optional("staleness_s", staleness_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(10), std::chrono::minutes(1)});
  }
  bool operator==(const FleetConfig&) const = default;
};

/// Device supervision (lab seconds, not scaled).
struct DevicesConfig {
  /// A light whose status has not been heard for this long is lost: its intersection goes to
  /// fail-safe flash.
  nanoseconds timeout_s = std::chrono::milliseconds(500);
  /// A light that shows something other than its command for this long is faulty.
  nanoseconds mismatch_s = std::chrono::seconds(1);
  /// The start-up flash lasts until every light of the intersection has reported. False runs
  /// the controllers without lights (SPaT only, e.g. a pure simulation or a benchmark).
  bool wait_for_lights = true;
  /// A fail-safe flash the SCM latched only because lights went silent (a network cut, a light
  /// host restarted) ends on its own once every light of the intersection reports again and
  /// follows the SCM for this long: the intersection restarts through start-up, as after a
  /// reset (event `failsafe_recovered`). 0: it lasts until `scmctl reset`, as every other
  /// fail-safe flash does.
  nanoseconds recover_s = std::chrono::seconds(1);
  /// At most this many automatic recoveries per intersection within an hour; the next lost-light
  /// flash lasts until `scmctl reset` (event `failsafe_recovery_exhausted`).
  int max_recoveries_per_hour = 20;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("wait_for_lights", wait_for_lights);
    a.Optional("recover_s", recover_s,
               config::Range<nanoseconds>{std::chrono::seconds(0), std::chrono::minutes(10)});
    a.Optional("max_recoveries_per_hour", max_recoveries_per_hour, config::Range{1, 100});
    a.Optional("timeout_s", timeout_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(100), std::chrono::minutes(1)});
    a.Optional("mismatch_s", mismatch_s,
               config::Range<nanoseconds>{std::chrono::milliseconds(100), std::chrono::minutes(1)});
  }
  bool operator==(const DevicesConfig&) const = default;
};

/// True for 1 to 64 letters, digits or '_', not starting with a digit (a ROS name token).
[[nodiscard]] inline bool IsOperatorName(const std::string& n) {
  if (n.empty() || n.size() > 64 || (n.front() >= '0' && n.front() <= '9')) return false;
  for (const char c : n) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    if (!ok) return false;
  }
  return true;
}

/// Who may change the city's state through the SCM (docs/scm.md, "Operators").
struct OperatorsConfig {
  /// Operator names. Operator `n` sends on /autodrive/scm/operator/<n>/request; with DDS
  /// Security only the identity /autodrive/operator/<n> may write there. Read-only commands are
  /// answered for anyone.
  std::vector<std::string> allowed;
  double rate_per_s = 50.0;  ///< requests per second per client, sustained
  double burst = 100.0;      ///< requests a client may send at once

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("allowed", allowed,
               config::Predicate{"names of 1 to 64 letters, digits or '_', not starting with a "
                                 "digit",
                                 [](const std::vector<std::string>& names) {
                                   for (const auto& n : names) {
                                     if (!IsOperatorName(n)) return false;
                                   }
                                   return true;
                                 }});
    a.Optional("rate_per_s", rate_per_s, config::Range{1.0, 10000.0});
    a.Optional("burst", burst, config::Range{1.0, 100000.0});
  }
  bool operator==(const OperatorsConfig&) const = default;
};

/// A whole city file.
struct CityConfig {
  std::string name;
  std::string map;  ///< the map: a layout or a map.yaml, relative to the city file
  /// Lab seconds per configured second: 1.0 when timings are written in lab seconds; e.g. 0.5
  /// to run full-scale timings twice as fast.
  double time_scale = 1.0;
  SafetyConfig safety;
  StartUpConfig start_up;
  std::vector<IntersectionConfig> intersections;
  FleetConfig fleet;
  DevicesConfig devices;
  OperatorsConfig operators;
  /// Empty: one district, the whole city on one domain (the domain each program is given).
  std::vector<maps::DistrictConfig> districts;
  /// The simulator's section (vehicle_sim/sim_config.h): carried, not read, by the SCM.
  std::optional<config::ForeignSection> sim;
  /// The Eye's section (eye/eye_config.h): carried, not read, by the SCM.
  std::optional<config::ForeignSection> eye;
  /// SUMO co-simulation's section (traffic/traffic_config.h): carried, not read, by the SCM.
  std::optional<config::ForeignSection> traffic;
  /// The launcher's section (city/launcher/launch_config.h): carried, not read, by the SCM.
  std::optional<config::ForeignSection> launch;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("map", map);
    a.Optional("time_scale", time_scale, config::Range{0.01, 100.0});
    a.Optional("safety", safety);
    a.Optional("start_up", start_up);
    a.Required("intersections", intersections);
    a.Optional("fleet", fleet);
    a.Optional("devices", devices);
    a.Optional("operators", operators);
    a.Optional("districts", districts);
    a.Optional("sim", sim);
    a.Optional("eye", eye);
    a.Optional("traffic", traffic);
    a.Optional("launch", launch);
  }
  bool operator==(const CityConfig&) const = default;
};

}  // namespace autodrive::scm
