#pragma once
/// @file
/// A city plan as a program of SUMO's NEMA controller (`tlLogic type="NEMA"`, SUMO 1.15): the
/// plan's ring form (`scm::RingPlanOf`) with each phase's timing and a light state built from
/// its signal groups, so that SUMO can run the same plan as the SCM's controller and the two can
/// be compared (docs/controller-crosscheck.md).
///
/// How the ring form maps onto SUMO's NEMA controller (docs/controller-crosscheck.md,
/// research/controller.md §4):
/// - SUMO's rings have four places, two each side of its two barriers. A one-ring plan of n
///   phases (2 to 4) fills ring 1 as 1,2 | 3,4 (n = 4), 1,2 | 3,0 (n = 3) or 1,0 | 2,0 (n = 2)
///   and repeats it as ring 2 (split phasing: SUMO's way to run one ring);
/// - `barrierPhases` are the phases that end at the barrier closing the ring (its last phase),
///   `coordinatePhases` those that end at the middle barrier (the last phase before it);
/// - a fixed-time plan is coordinated (`coordinate-mode`, TS2): SUMO starts the coordinated
///   phase's green at its `offset` on its own clock, so the exported offset is the plan's offset
///   plus that phase's green start in the plan's cycle; phase 1's green starts at the plan's
///   offset, as in the SCM's controller;
/// - recalls: `maxRecall` for max recall, `minRecall` for min recall (written even when empty:
///   SUMO's default puts every phase on min recall); `latchingDetectors` for the phases whose
///   detector memory locks (non_lock false); `fixForceOff` for a fixed-time plan;
/// - per phase `minDur` = min green, `maxDur` = max 1, `vehext` = passage, `yellow`, `red` = red
///   clearance, `name` = the phase number, `state` one character per link of the junction's
///   traffic light: 'G' for the movements of the phase's groups, 'r' for the others (link i is
///   movement i of the intersection, as `maps::ExportSumo` numbers them).

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/time.h"
#include "maps/map.h"
#include "scm/core/city.h"
#include "scm/core/ring_plan.h"

namespace autodrive::traffic::nema {

/// The programID the export gives its tlLogic.
inline constexpr const char* kProgramId = "NEMA";

/// One phase of SUMO's NEMA program.
struct NemaPhase {
  std::uint32_t number = 0;  ///< the NEMA phase number (`name`)
  Duration min_green{0};     ///< minDur
  Duration max_green{0};     ///< maxDur
  Duration passage{0};       ///< vehext
  Duration yellow{0};
  Duration red_clear{0};            ///< red
  std::string state;                ///< one character per link: 'G' or 'r'
  std::vector<std::size_t> groups;  ///< the signal groups it drives (indices)
  std::vector<std::size_t> links;   ///< the link indices its groups' movements have
};

/// A NEMA program for SUMO's `tlLogic type="NEMA"`. Value type.
struct NemaProgram {
  std::string tls;  ///< the junction's traffic light id (the intersection's name)
  std::string program_id = kProgramId;
  /// ring1 and ring2: four places each, 0 where a place is empty.
  std::array<std::vector<std::uint32_t>, 2> rings;
  std::array<std::uint32_t, 2> barrier_phases{};     ///< barrierPhases (ring 1, ring 2)
  std::array<std::uint32_t, 2> coordinate_phases{};  ///< coordinatePhases (ring 1, ring 2)
  bool coordinated = false;    ///< coordinate-mode: a fixed-time plan, offset honoured
  bool fix_force_off = false;  ///< fixForceOff
  /// The tlLogic offset: where the coordinated phase's green starts on SUMO's clock (mod cycle).
  Duration offset{0};
  /// The plan's offset: where phase 1's green starts on SUMO's clock (mod cycle).
  Duration plan_offset{0};
  Duration cycle{0};  ///< total-cycle-length: the sum of ring 1's max greens and clearances
  std::vector<std::uint32_t> min_recall, max_recall, latching;
  std::vector<NemaPhase> phases;  ///< by number, ascending
  std::size_t links = 0;          ///< the number of the traffic light's links

  /// The phase numbered `number`, or null.
  [[nodiscard]] const NemaPhase* Find(std::uint32_t number) const;
};

/// The NEMA program of `plan` (the ring form of a plan of `x`) at intersection `map_x` (the map's
/// intersection of `x`). Throws `InputError` naming what SUMO's NEMA controller cannot run: a
/// plan without phases (flash, dark), more than one ring, fewer than 2 or more than 4 phases in
/// the ring, a phase number above 8, a signal group driven by two phases, a phase without a
/// yellow, a pedestrian or soft recall, walk or pedestrian clearance times, a red revert.
[[nodiscard]] NemaProgram NemaProgramOf(const maps::Intersection& map_x,
                                        const scm::IntersectionModel& x, const scm::RingPlan& plan);

/// A plan of a city's signalised intersection.
struct PlanRef {
  const scm::IntersectionModel* model = nullptr;
  std::size_t plan = 0;  ///< index into `model->plans`
};

/// The plan called `plan` of the intersection called `intersection` (its name or decimal id).
/// Throws `InputError` naming the signalised intersections, or the intersection's plans.
[[nodiscard]] PlanRef FindPlan(const scm::City& city, const std::string& intersection,
                               const std::string& plan);

/// The NEMA program of plan `ref` of `city` (its ring form, `scm::RingPlanOf`). Throws as
/// `NemaProgramOf` above, with the plan's name in front.
[[nodiscard]] NemaProgram NemaProgramOf(const scm::City& city, const PlanRef& ref);

/// Output files SUMO writes for the light (`timedEvent`s), absolute paths; empty: none.
struct NemaOutputs {
  std::filesystem::path switch_times;  ///< SaveTLSSwitchTimes: every link's green
  std::filesystem::path states;        ///< SaveTLSStates: the state at every step
};

/// A SUMO additional file with `program` as one `tlLogic` (and the `timedEvent`s of
/// `outputs`), as XML text.
[[nodiscard]] std::string NemaAdditionalXml(const NemaProgram& program,
                                            const NemaOutputs& outputs = {});

/// Seconds as SUMO's attributes want them: up to millisecond precision, no trailing zeros
/// ("8", "2.5", "0.125").
[[nodiscard]] std::string SumoSeconds(Duration d);

}  // namespace autodrive::traffic::nema
