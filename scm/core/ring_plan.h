#pragma once
/// @file
/// A plan in the form real controllers use (docs/controller.md): NTCIP 1202 *phases*, each a
/// timing unit (a `phaseTable` row) that drives one or more signal groups (its channels),
/// served in the order of each ring's sequence (`sequenceData`), rings running together where
/// `phaseConcurrency` lets them. Field names follow the NTCIP objects; every duration is lab
/// time (NTCIP's tenths and seconds are only units of the wire, not of this model).
///
/// A stage plan of the city file (`plans[].phases` of groups) is a one-ring sequence whose
/// phases drive several groups: `RingPlanOf` converts it, timings carried over, and
/// `scmctl config validate` prints the result. Pure: no I/O.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/time.h"
#include "scm/core/city.h"

namespace autodrive::scm {

/// A phase's recall (NTCIP phaseOptions bits 6–9): a call placed whatever the detectors say.
enum class Recall {
  kNone,  ///< served only on a call
  kMin,   ///< minimum vehicle recall: always called, green for its min green unless extended
  kMax,   ///< maximum vehicle recall: always called and held to its max (fixed time)
  kPed,   ///< pedestrian recall: a walk every cycle
  kSoft,  ///< soft recall: called when no conflicting phase is
};
/// "none", "min", "max", "ped", "soft".
[[nodiscard]] std::string_view ToString(Recall recall);

/// An NTCIP 1202 phase (a `phaseTable` row), lab time.
struct RingPhase {
  std::uint32_t number = 0;                ///< phaseNumber (1..255)
  std::vector<std::size_t> groups;         ///< the signal groups it drives (its channels), by index
  Duration min_green{0};                   ///< phaseMinimumGreen
  Duration passage{0};                     ///< phasePassage: the gap a call must come within
  Duration max1{0};                        ///< phaseMaximum1
  Duration max2{0};                        ///< phaseMaximum2
  Duration yellow{0};                      ///< phaseYellowChange
  Duration red_clear{0};                   ///< phaseRedClear
  Duration red_revert{0};                  ///< phaseRedRevert
  Duration walk{0};                        ///< phaseWalk
  Duration ped_clear{0};                   ///< phasePedestrianClear
  Recall recall = Recall::kNone;           ///< phaseOptions bits 6–9
  bool non_lock = false;                   ///< phaseOptions bit 5: non-locking detector memory
  bool dual_entry = false;                 ///< phaseOptions bit 10
  std::uint32_t ring = 1;                  ///< phaseRing
  std::vector<std::uint32_t> concurrency;  ///< phaseConcurrency: phase numbers of other rings
};

/// A plan as rings of phases (a pattern with its sequence), lab time.
struct RingPlan {
  std::vector<RingPhase> phases;  ///< by phase number, ascending
  /// sequenceData of each ring (sequenceRingNumber 1, 2, ...): phase numbers in service order.
  std::vector<std::vector<std::uint32_t>> rings;
  /// patternCycleTime: a fixed-time plan's cycle (each ring's greens, yellows and red
  /// clearances); zero for a plan that is not fixed-time.
  Duration cycle{0};
  /// patternOffsetTime: where the first phase's green starts in the cycle, after the system
  /// reference (local midnight).
  Duration offset{0};

  /// The phase numbered `number`, or null.
  [[nodiscard]] const RingPhase* Find(std::uint32_t number) const;
};

/// The one-ring form of stage plan `plan` of `x`: phase k + 1 drives stage k's groups, in stage
/// order, with
/// - min_green: the longest min green of its groups;
/// - max1 and max2: the stage's green (a fixed-time green, or an actuated stage's max);
/// - passage: the plan's `extension_s` (actuated), zero otherwise;
/// - yellow and red_clear: the longest of the groups it ends, i.e. those the next stage does not
///   keep green (zero when the next stage keeps them all: the phase change needs no clearance);
/// - recall: max for a fixed-time plan; in an actuated plan min for a stage with a group no
///   detector calls (it is always called), none otherwise;
/// - non_lock: true (a call counts only while a detector is occupied, as the controller has it);
/// - ring 1, no concurrency; cycle (fixed time) and offset as the plan's.
/// Flash and dark plans have no phases: an empty ring plan.
[[nodiscard]] RingPlan RingPlanOf(const IntersectionModel& x, const Plan& plan);

/// The ring plan as a table for people (`scmctl config validate`): one line per phase with its
/// NTCIP timing and groups, then the rings' sequences and the cycle.
[[nodiscard]] std::string DescribeRingPlan(const IntersectionModel& x, const RingPlan& plan);

}  // namespace autodrive::scm
