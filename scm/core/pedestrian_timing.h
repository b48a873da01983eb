#pragma once
/// @file
/// The MUTCD's pedestrian timing rules as pure functions (docs/controller.md, "Pedestrians"):
/// the least walk and pedestrian clearance a crossing needs, and the check of a configured
/// timing against them. Everything here is full scale: lengths in full-scale metres (the city
/// loader multiplies the lab's by the lab's scale), times in seconds as a full-size controller
/// runs them. No I/O.
///
/// The rules (MUTCD 2009 Section 4E.06, Figure 4E-2):
/// - **walk** at least 7 s; as short as 4 s where pedestrian volumes do not need 7 s;
/// - **pedestrian clearance** (flashing don't walk) at least the crossing to the far side of the
///   traveled way at 3.5 ft/s (1.07 m/s; 4E.06 P07); the 2003 MUTCD used 4.0 ft/s (1.22 m/s);
/// - **walk + pedestrian clearance** at least the distance from the push button (6 ft back from
///   the kerb where there is none) to the far side at 3 ft/s (0.91 m/s; 4E.06 P14), any extra
///   time going to the walk; the 2003 MUTCD had no such rule;
/// - **buffer** (steady don't walk before a conflicting green: the yellow and red clearance of
///   the parallel vehicle phase) at least 3 s (Figure 4E-2).
///
/// Every minimum is rounded up to whole seconds, as the FHWA worked example does and as NTCIP
/// 1202 carries phaseWalk and phasePedestrianClear (seconds): a 130 ft crossing with its push
/// button 60 ft back needs 130 / 3.5 = 37.1 -> 38 s of clearance and (130 + 60) / 3 = 63.3 ->
/// 64 s of walk and clearance, so a 26 s walk (2003 rules: 7 s walk + 130 / 4 = 32.5 -> 33 s).

#include <optional>
#include <string>
#include <vector>

namespace autodrive::scm {

/// Walking speed for the pedestrian clearance: 3.5 ft/s (MUTCD 2009 4E.06 P07).
inline constexpr double kClearanceWalkingSpeedMps = 1.07;
/// Walking speed for the pedestrian clearance before 2009: 4.0 ft/s (MUTCD 2003).
inline constexpr double kClearanceWalkingSpeed2003Mps = 1.22;
/// Walking speed from the push button for walk + clearance: 3 ft/s (MUTCD 2009 4E.06 P14).
inline constexpr double kButtonWalkingSpeedMps = 0.91;
/// Where P14 measures from when a crossing has no push button: 6 ft back from the kerb (m).
inline constexpr double kNoButtonSetbackM = 1.83;
/// The least walk (s): 7 s, or 4 s where pedestrian volumes do not need 7 s (MUTCD 4E.06).
inline constexpr double kMinWalkS = 7.0;
inline constexpr double kMinWalkLowVolumeS = 4.0;
/// The least buffer interval (s): steady don't walk before a conflicting green (Figure 4E-2).
inline constexpr double kMinBufferS = 3.0;

/// A pedestrian crossing as the MUTCD measures it, full-scale metres.
struct PedestrianCrossing {
  double length_m = 0.0;  ///< from the kerb to the far side of the traveled way
  /// From the push button to the kerb where the crossing starts.
  double button_setback_m = kNoButtonSetbackM;
};

/// Which MUTCD's rules: 2009 (current walking speeds) or 2003 (4 ft/s, no push-button check).
enum class MutcdEdition { k2009, k2003 };

/// The least pedestrian timing a crossing needs, whole seconds (rounded up) with the exact
/// figures they come from.
struct PedestrianMinimums {
  double walk_s = 0.0;             ///< the walk floor: 7 s, or 4 s at low volume
  double ped_clear_s = 0.0;        ///< length / clearance walking speed, rounded up
  double ped_clear_exact_s = 0.0;  ///< length / clearance walking speed
  double walk_and_clear_s = 0.0;   ///< (length + setback) / 0.91 m/s, rounded up (2003: 0)
  double walk_and_clear_exact_s = 0.0;
  /// The shortest timing that meets every rule: the walk floor, raised so that walk + clearance
  /// reaches `walk_and_clear_s` (the FHWA example's 26 s), and `ped_clear_s`.
  double shortest_walk_s = 0.0;
  [[nodiscard]] double ShortestTotalS() const { return shortest_walk_s + ped_clear_s; }
};

/// The MUTCD minimums of `crossing` under `edition`'s rules; `low_pedestrian_volume` allows the
/// 4 s walk.
[[nodiscard]] PedestrianMinimums MutcdPedestrianMinimums(
    const PedestrianCrossing& crossing, bool low_pedestrian_volume,
    MutcdEdition edition = MutcdEdition::k2009);

/// The minimums of `crossing` for people, one line per rule with how it comes about and the
/// shortest timing that meets them all (`scmctl pedestrian-timing`). `feet`: lengths also in
/// feet (the MUTCD's unit).
[[nodiscard]] std::string DescribePedestrianMinimums(const PedestrianCrossing& crossing,
                                                     bool low_pedestrian_volume,
                                                     MutcdEdition edition, bool feet = false);

/// One rule a pedestrian timing breaks.
struct PedestrianViolation {
  std::string rule;  ///< e.g. "MUTCD 2009 4E.06 P14: walk + pedestrian clearance"
  double configured_s = 0.0;
  double minimum_s = 0.0;
  /// The whole message: the rule, the configured time and the minimum with how it comes about,
  /// e.g. "walk + ped clear 7 s + 8 s = 15 s is below (8.4 m + 1.4 m) / 0.91 m/s = 10.8 s,
  /// rounded up 11 s; rule: MUTCD 2009 4E.06 P14: ...".
  std::string message;
};

/// A configured pedestrian timing (seconds, full scale).
struct PedestrianTiming {
  double walk_s = 0.0;       ///< steady walk (NTCIP phaseWalk)
  double ped_clear_s = 0.0;  ///< flashing don't walk (NTCIP phasePedestrianClear)
};

/// Checks `timing` for `crossing` against the 2009 MUTCD minimums (walk, pedestrian clearance,
/// walk + pedestrian clearance from the push button); empty when it meets them all.
[[nodiscard]] std::vector<PedestrianViolation> CheckPedestrianTiming(
    const PedestrianCrossing& crossing, const PedestrianTiming& timing, bool low_pedestrian_volume);

/// Checks a buffer interval (the yellow and red clearance of a vehicle phase that runs parallel
/// to the crossing, s) against the MUTCD's 3 s; nothing when it is long enough.
[[nodiscard]] std::optional<PedestrianViolation> CheckBufferInterval(double buffer_s);

}  // namespace autodrive::scm
