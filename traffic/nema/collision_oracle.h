#pragma once
/// @file
/// The intergreen collision oracle (issue 37; research/controller.md §4.3 M8;
/// docs/controller-crosscheck.md, "Intergreen oracle"): are a city's intergreens safe by SUMO's
/// judgement?
///
/// The SCM's core (`scm::CityRuntime`: every signalised intersection's controller and conflict
/// monitor, on its scheduled plan) drives SUMO's lights through the lamps, as the
/// co-simulation does: each head shows its group's aspect (flashing at 1 Hz as the light host
/// flashes it), its lamp is reported to `traffic::CoSimulation` (lamp_mapping.h: the lamps
/// become SUMO's link states), which steps SUMO on the city's network (x14) in this process.
/// SUMO runs with 0.1 s steps and junction collision checks (`--collision.check-junctions`,
/// `--collision.action warn`); the traffic is oracle_traffic.h's: slow clearing and fast
/// entering vehicles that trust the signal, through every movement a conflicting green meets.
/// Every collision SUMO reports is kept (its collision output), with the two vehicles' movements
/// and what their groups showed; the verdict counts the junction collisions.
///
/// The negative control (`IntergreenChange::kScale` 0.5, `--halve-intergreens`) halves, in
/// memory after loading, every group's yellow plus red clearance (the yellow kept, the red
/// clearance cut, so that yellow + red is half; a yellow longer than the half is cut to it and
/// the red clearance is then 0), every entry of the intergreen matrix (so that the conflict
/// monitor lets the halved timings run) and every fixed-time cycle with them. Other factors
/// measure where collisions begin; `kMatrix` runs each group's yellow + red clearance at the
/// largest entry of its row of the matrix, the least the loader would accept were it not for
/// the ITE red clearance. The city loader refuses such timings, so this is the only way to run
/// them.
///
/// One simulation a process (libsumo).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/time.h"
#include "scm/core/city.h"

namespace autodrive::traffic::nema {

/// How the run alters the city's intergreens (above).
struct IntergreenChange {
  enum class Kind { kNone, kScale, kMatrix };
  Kind kind = Kind::kNone;
  double factor = 1.0;  ///< kScale: yellow + red clearance and the matrix times this, in (0, 1]

  /// "the city's timings", "every intergreen x 0.5", "every intergreen at its matrix entry".
  [[nodiscard]] std::string Describe() const;
};

/// What to run.
struct CollisionOracleOptions {
  Duration duration = std::chrono::hours(1);  ///< simulated time
  /// The local time of day at the start: it chooses each intersection's scheduled plan, which
  /// must be fixed time for the whole run (12:00: the shipped cities' `day` plans).
  Duration time_of_day = std::chrono::hours(12);
  IntergreenChange intergreens;  ///< the negative control and other alterations (above)
  /// Mean time between two vehicles of one ingress lane (oracle_traffic.h).
  Duration headway = std::chrono::seconds(6);
  std::uint64_t seed = 1;  ///< SUMO's seed (the flows' arrivals)
  /// Traffic through this intersection only (name or id); every intersection's controller runs.
  std::optional<std::string> intersection;
  std::filesystem::path out_dir;
  Duration step = std::chrono::milliseconds(100);
  /// Called with a line of progress now and then (simulated time, vehicles, collisions so far).
  std::function<void(const std::string&)> progress;
};

/// One collision SUMO reported (two vehicles that started to overlap; the records of the same
/// pair at consecutive steps are one collision).
struct OracleCollision {
  double time_s = 0.0;   ///< SUMO's time of its first record
  std::string type;      ///< SUMO's collision type
  std::string lane;      ///< where SUMO saw it (":<junction>_..." inside a junction)
  std::string junction;  ///< the junction, for one inside a junction; else empty
  bool in_junction = false;
  std::string collider, victim;                             ///< SUMO's vehicle ids
  std::string collider_type, victim_type;                   ///< clearing / entering
  double collider_speed_mps = 0.0, victim_speed_mps = 0.0;  ///< SUMO's
  std::string collider_movement, victim_movement;           ///< the map's names
  /// The two vehicles came from groups of one intersection that conflict: what an intergreen
  /// keeps apart. (Otherwise, for instance, two vehicles of one approach that part in the box,
  /// one ignoring the other as a junction foe.)
  bool conflicting_groups = false;
  /// What the two vehicles' groups showed: "group 1 (east) green ended 2.4 s before" ...
  std::string signals;
};

/// The least time from a group's end of green to a conflicting group's next green seen in the
/// run, beside the matrix entry.
struct ObservedIntergreen {
  std::string intersection;
  std::string clearing, entering;  ///< "group 1 (east)"
  double matrix_s = 0.0;           ///< the model's entry (halved in the negative control)
  double observed_s = 0.0;         ///< the least seen
  int transitions = 0;             ///< how many times it was seen
};

/// What a run found; the reports are written to `<out>/report.txt` and `<out>/report.json`.
struct CollisionOracleResult {
  int junction_collisions = 0;
  /// Of them, between vehicles of conflicting groups (`OracleCollision::conflicting_groups`).
  int intergreen_collisions = 0;
  int other_collisions = 0;  ///< on lanes (rear-end), not in a junction
  std::vector<OracleCollision> collisions;
  std::vector<ObservedIntergreen> intergreens;
  std::int64_t vehicles_departed = 0;
  std::int64_t vehicles_arrived = 0;
  /// SUMO's statistics output: vehicles its flows made, and of them those still waiting to go
  /// in at the end (the approaches are saturated: oracle_traffic.h).
  std::int64_t vehicles_loaded = 0;
  std::int64_t vehicles_waiting = 0;
  std::int64_t sumo_collisions = 0;  ///< SUMO's own count (records, not pairs)
  std::int64_t emergency_stops = 0;  ///< SUMO's count of emergency braking
  std::uint64_t monitor_violations = 0;
  double cpu_s = 0.0;            ///< this process's CPU time for the run
  double sumo_step_cpu_s = 0.0;  ///< of which inside SUMO's steps
  std::string text;              ///< the text report
  std::filesystem::path text_report, json_report;
};

/// Alters every intergreen of `city` in memory as `change` says (above), to whole `step`s
/// (rounded down for a factor, up to the matrix), with the fixed-time cycles that follow.
/// Returns a line per group and plan saying what changed. Throws `InputError` for a factor
/// outside (0, 1].
std::vector<std::string> ChangeIntergreens(scm::City& city, const IntergreenChange& change,
                                           Duration step);

/// Checks `options` against `city` without running anything: the step and duration, a run that
/// ends by midnight, fixed-time scheduled plans throughout, a known `intersection`. Returns a
/// line per intersection naming its plans. Throws `InputError` naming what is wrong.
std::vector<std::string> CheckCollisionOracleOptions(const scm::City& city,
                                                     const CollisionOracleOptions& options);

/// Runs the oracle on `city` and writes its files into `options.out_dir` (created): network/,
/// oracle.rou.xml, collisions.xml, sumo.log, report.txt, report.json. Throws `InputError` for
/// bad options (a scheduled plan that is not fixed time during the run, an unknown
/// intersection, a run past midnight, a step that does not divide the duration),
/// `traffic::SumoError` when SUMO fails.
[[nodiscard]] CollisionOracleResult RunCollisionOracle(const scm::City& city,
                                                       const CollisionOracleOptions& options);

}  // namespace autodrive::traffic::nema
