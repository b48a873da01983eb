#pragma once
/// @file
/// The crosscheck: one plan of one intersection run by the SCM's controller
/// (`scm::IntersectionController`) and by SUMO's NEMA controller (libsumo, in this process) in
/// lockstep on one 0.1 s timeline, with the same detector calls, and every green, yellow and red
/// clearance of each phase compared (docs/controller-crosscheck.md).
///
/// The run: the city's network exported as the co-simulation exports it (`maps::ExportSumo`,
/// x14) into `<out>/network/`, the plan's NEMA program (`NemaProgramOf`) in
/// `<out>/<tls>.nema.add.xml`, SUMO's SaveTLSSwitchTimes and SaveTLSStates outputs in
/// `<out>/tls_switches.xml` and `<out>/tls_states.xml`, no vehicles, SUMO's program set to
/// "NEMA". Our controller runs the plan as the operator's (whatever the schedule says) with its
/// day clock placed so that its cycle zero (local midnight + the plan's offset) is SUMO's time 0
/// + the offset; it starts with its start-up flash and all red, so the comparison begins at
/// the first cycle start at which both run the plan. Calls reach SUMO through
/// `LaneArea::overrideVehicleNumber` on its `<tls>_NEMA_D<phase>.<k>` detectors and our
/// controller through its calls (the phase's groups). SUMO's intervals come from its states
/// output (exact times; TraCI would show each change one step late) and its greens are checked
/// against the switch-times output. Both comparisons are made (comparison.h): each interval
/// with SUMO's nearest (`kPairs`), and both sequences place by place (`kSequence`, for actuated
/// runs), whose stretches of differences are put down to rules (diagnosis.h).
///
/// libsumo runs one simulation per process: call `RunCrosscheck` once per process.

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "traffic/nema/call_script.h"
#include "traffic/nema/comparison.h"

#include "common/time.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {

/// Calls drawn from a seed (`RandomCallScript`) instead of a script.
struct RandomCalls {
  std::uint64_t seed = 0;
  RandomCallParams params;
};

/// What to run.
struct CrosscheckOptions {
  std::string intersection;  ///< its name or decimal id
  std::string plan;          ///< the plan's name
  int cycles = 10;           ///< cycles compared (after the start-up), unless `duration` is set
  /// When set, the compared window ends at this time on SUMO's clock instead of after `cycles`
  /// (the run goes on for one more cycle, the sum of max greens and clearances, so that the
  /// intervals begun in the window end).
  std::optional<Duration> duration;
  CallScript calls;  ///< detector calls (none: recalls only)
  /// When set, the calls are drawn from this seed for [`calls_from`, the window's end) instead
  /// of `calls`, for the phases with a detector (not on recall), and written to
  /// `<out>/calls.txt` (replay it with `calls`).
  std::optional<RandomCalls> random_calls;
  /// Which comparison gives the verdict (both are reported).
  ComparisonMode compare = ComparisonMode::kPairs;
  std::filesystem::path out_dir;
  Duration step = std::chrono::milliseconds(100);
  Duration tolerance = std::chrono::milliseconds(100);
  /// When our controller starts, on SUMO's clock (negative: it runs alone before SUMO starts).
  Duration our_start{0};
  /// Test only: SUMO's max green (maxDur) of these phases instead of the plan's (its cycle
  /// follows), to show that the crosscheck sees a difference.
  std::map<std::uint32_t, Duration> sumo_max_green;
};

/// What a run found; the reports are written to `<out>/report.txt` and `<out>/report.json`.
struct CrosscheckResult {
  RunFacts facts;
  Verdicts verdicts;  ///< both comparisons, and the mode that gives `passed`
  bool passed = false;
  std::string text;  ///< the text report
  std::filesystem::path text_report, json_report;
};

/// Runs the crosscheck of `options` on `city` and writes its files into `options.out_dir`
/// (created). Throws `InputError` for bad input (unknown intersection or plan, a plan SUMO's
/// NEMA controller cannot run, calls of a phase the plan does not have or has on min recall
/// (no detector: SUMO's detector would take the call, ours none), a run longer than a
/// day, a step that does not divide the plan's times or the duration, a duration that ends
/// before the window starts, bad random call parameters), `traffic::SumoError` (sumo_api.h) with
/// SUMO's message when SUMO fails.
[[nodiscard]] CrosscheckResult RunCrosscheck(const scm::City& city,
                                             const CrosscheckOptions& options);

/// Exports `city`'s network into `dir` (as the crosscheck does) and runs SUMO's `sumo` program
/// on it with `additional` for one second: throws `InputError` with SUMO's output when SUMO
/// refuses the file. Returns SUMO's output (its warnings).
std::string CheckWithSumo(const scm::City& city, const std::filesystem::path& additional,
                          const std::filesystem::path& dir);

}  // namespace autodrive::traffic::nema
