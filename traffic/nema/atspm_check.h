#pragma once
/// @file
/// The ATSPM check against SUMO (issue 37, "ATSPM measures match independent records";
/// docs/atspm.md, "Checked against SUMO"): do the SCM's arrivals on green and split monitor,
/// computed by scm/atspm from the controller's own high-resolution log, agree with what SUMO's
/// own output files say happened?
///
/// The run is the intergreen oracle's co-simulation (collision_oracle.h): the SCM's core
/// (`scm::CityRuntime`, every controller and conflict monitor, on its scheduled fixed-time plan)
/// drives SUMO's lights through the lamps, lockstep at 0.1 s, with the oracle's vehicles through
/// one intersection, here at ordinary random arrivals (a vehicle every `headway` per ingress
/// lane on average) so that arrivals on green are neither 0 nor 100 %. SUMO's vehicles reach
/// the SCM's detectors as in the co-simulation: each step's vehicles go into a
/// `scm::FleetRegistry` (`ObserveTraffic`, as the daemon takes `/autodrive/scm/traffic`), which
/// `CityRuntime::Step` asks for its plan's detector zones and logs 82/81 per group channel.
///
/// **The arrival detection point.** Both sides detect at one physical place per ingress lane:
/// `setback_m` (lab m) upstream of the stop line. For the SCM, every fixed-time plan of the
/// intersection gets, in memory, a detector zone per ingress lane and group,
/// [`setback_m` - `zone_m`, `setback_m`] from the stop line (a fixed-time controller ignores
/// calls; the zones only make it log 82/81); a vehicle's footprint reaching into it is an 82, so
/// its front crossing `setback_m`. For SUMO, an `instantInductionLoop` at the same place
/// (lane length - `setback_m` x scale on the ingress lane's last SUMO piece), whose `enter`
/// records are the same front crossing. Upstream of the stop line rather than at it (where the
/// city's actuated plans have their zones), so that a vehicle arriving at a queue is counted
/// once: at a stop-line zone a queue is one long occupancy and many arrivals one 82.
///
/// Computed:
/// 1. **SUMO, from its files alone** (`ReadSumoRecords`, pugixml): the loops (additional file:
///    loop id `aog_p<phase>_<lane>` names its phase), their `enter` records, the green windows
///    of the links from the loops' lanes (`SaveTLSSwitchTimes`), their yellows (`SaveTLSStates`
///    with the network's link indices); per phase and bin of 15 min, the share of entries inside
///    a green window, counting entries between the phase's first and last end of yellow (the
///    PCD's red-to-red cycles); per green, green + yellow + red (to the next green of another
///    phase of the light).
/// 2. **The SCM, from its log alone**: `atspm::Pcd` (bins) and `atspm::SplitMonitor` on the
///    controller's hires events (`TakeHiresEvents`), the channel map from the ring plan.
/// 3. The differences: the check passes when every phase and bin's arrivals on green agree
///    within `aog_tolerance_pp` percentage points and every service's split within
///    `split_tolerance`. SUMO's figure is computed twice: at the loop stamps as they are
///    (literal), and at the time the SCM's detector reads each entry, the step after the SUMO
///    step that moved the vehicle past the loop (SUMO stamps an entry inside the move of step
///    `ceil(t / step)`, interval (label - step, label], a move made under that label's lights;
///    the SCM reads that step's positions at its next control step). The verdict is on the
///    second unless `literal_verdict`: a vehicle crossing within 0.1-0.2 s before a green
///    boundary is on the other side for the SCM, one vehicle being 3.6-5 pp of a lab bin. Each loop
///    entry is also paired with the SCM's 82 that saw it (the lag and any arrival the two place
///    differently are reported, to explain a difference).
///
/// One simulation a process (libsumo).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/time.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {

/// What to run.
struct AtspmCheckOptions {
  std::string intersection;                   ///< name or id (required)
  Duration duration = std::chrono::hours(1);  ///< simulated time
  /// Local time of day at the start: the scheduled plans, fixed time for the whole run.
  Duration time_of_day = std::chrono::hours(12);
  Duration headway = std::chrono::seconds(40);  ///< mean time between vehicles of a lane
  std::uint64_t seed = 1;                       ///< SUMO's seed
  std::filesystem::path out_dir;
  Duration step = std::chrono::milliseconds(100);
  Duration bin = std::chrono::minutes(15);
  double setback_m = 0.5;  ///< the detection point: lab m upstream of the stop line
  double zone_m = 0.01;    ///< the SCM's zone length (lab m) downstream from there
  double aog_tolerance_pp = 1.0;
  Duration split_tolerance = std::chrono::milliseconds(100);
  /// A test's perturbation: SUMO's green windows of the lowest-numbered phase moved by this
  /// when read (the check must then fail).
  Duration test_shift_sumo_windows{0};
  /// The verdict on the literal figure (loop stamps inside SUMO's greens) instead of the entries
  /// at the SCM's read times (above).
  bool literal_verdict = false;
  std::function<void(const std::string&)> progress;
};

/// One phase's records as SUMO's files give them, seconds of SUMO's clock.
struct SumoPhaseRecords {
  std::uint16_t phase = 0;
  std::vector<std::string> lanes;                  ///< its loops' lanes
  std::vector<double> entries;                     ///< loop `enter` times, ascending
  std::vector<std::pair<double, double>> greens;   ///< its links' green windows [begin, end)
  std::vector<std::pair<double, double>> yellows;  ///< its links' yellows [begin, end)
};

/// The files SUMO wrote.
struct SumoFiles {
  std::filesystem::path net;         ///< the network (link indices of the states)
  std::filesystem::path additional;  ///< the loops and the timed events
  std::filesystem::path loops;       ///< the loops' output
  std::filesystem::path switches;    ///< SaveTLSSwitchTimes
  std::filesystem::path states;      ///< SaveTLSStates
  std::string tls;                   ///< the traffic light
};

/// SUMO's side: its records by phase.
struct SumoRecords {
  std::vector<SumoPhaseRecords> phases;
  int links_disagreeing = 0;
};
/// SUMO's side from its files alone, by phase (ascending). Links of one phase whose green
/// windows differ are counted in `links_disagreeing` (their union is taken). Throws
/// `InputError` naming a file that cannot be read.
[[nodiscard]] SumoRecords ReadSumoRecords(const SumoFiles& files);

/// One phase and bin: arrivals on green by both.
struct AogRow {
  std::uint16_t phase = 0;
  double bin_start_s = 0.0;
  int scm_volume = 0, scm_on_green = 0;
  /// SUMO, literal: loop entries at their stamps inside the switch-time greens.
  int sumo_volume = 0, sumo_on_green = 0;
  double scm_percent = 0.0, sumo_percent = 0.0;
  double difference_pp = 0.0;  ///< SCM - SUMO
  bool ok = true;
  /// SUMO, each entry at the time the SCM's detector reads it (the step after SUMO's step that
  /// moved the vehicle past the loop).
  int read_volume = 0, read_on_green = 0;
  double read_percent = 0.0;
  double read_difference_pp = 0.0;  ///< SCM - SUMO read
  bool read_ok = true;
};

/// One service of a phase: the SCM's split monitor against SUMO's green + yellow + red.
struct SplitRow {
  std::uint16_t phase = 0;
  double green_start_s = 0.0;  ///< the SCM's begin green
  double scm_green_s = 0.0, scm_yellow_s = 0.0, scm_red_s = 0.0, scm_split_s = 0.0;
  double sumo_green_s = 0.0, sumo_yellow_s = 0.0, sumo_red_s = 0.0, sumo_split_s = 0.0;
  double difference_s = 0.0;  ///< split, SCM - SUMO
  bool ok = true;
};

/// A loop entry and the SCM's 82 that saw it, placed differently by the two.
struct ArrivalDifference {
  std::uint16_t phase = 0;
  double sumo_s = 0.0, scm_s = 0.0;
  bool sumo_green = false, scm_green = false;
  std::string why;
};

/// What the check found; written to `<out>/report.txt` and `<out>/report.json`.
struct AtspmCheckResult {
  bool passed = false;          ///< the verdict: `passed_read`, or `passed_literal` when asked
  bool passed_literal = false;  ///< AoG at the loop stamps within tolerance, and the splits
  bool passed_read = false;     ///< AoG at the SCM's read times within tolerance, and the splits
  std::vector<AogRow> aog;
  std::vector<SplitRow> splits;
  int splits_unmatched = 0;             ///< SCM services with no SUMO green within 1 s (fail)
  double max_aog_difference_pp = 0.0;   ///< literal
  double max_read_difference_pp = 0.0;  ///< at the read times
  int read_time_matches = 0;            ///< pairs whose 82 is exactly at the entry's read time
  double max_split_difference_s = 0.0;
  int loop_entries = 0, detector_ons = 0, paired = 0;
  double lag_min_s = 0.0, lag_max_s = 0.0, lag_mean_s = 0.0;  ///< SCM 82 - loop entry
  std::vector<ArrivalDifference> differences;
  int links_disagreeing = 0;
  std::int64_t vehicles_departed = 0;
  std::uint64_t monitor_violations = 0;
  std::uint64_t hires_dropped = 0;
  double cpu_s = 0.0;
  std::string text;
  std::filesystem::path text_report, json_report;
};

/// Runs the check. Throws `InputError` for bad options (an unknown intersection, a plan that is
/// not fixed time during the run, a detection point SUMO cannot hold), `traffic::SumoError` when
/// SUMO fails.
[[nodiscard]] AtspmCheckResult RunAtspmCheck(const scm::City& city,
                                             const AtspmCheckOptions& options);

}  // namespace autodrive::traffic::nema
