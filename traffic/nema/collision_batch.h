#pragma once
/// @file
/// The intergreen collision oracle (collision_oracle.h) over every signalised intersection of a
/// city (`autodrive-scm-nema collisions CITY` without `--intersection`): one run per
/// intersection, each a child process of the program (libsumo runs one simulation per process),
/// in which every intersection's controller drives its lights and the oracle's traffic goes
/// through that intersection alone. Traffic at two intersections at once would test the
/// oracle's own queues instead: where an intersection's egress road is the next one's approach
/// (the small town's ramp between centre and north_t, one tile long), the vehicles queued on it
/// leave no room for a vehicle leaving the first box, which stops in it and is hit by the next
/// green's (measured: one such junction collision in 1200 s with the shipped timings and a
/// vehicle every 2 or 4 s a lane, none once the intersections ran apart). Writes
/// `<out>/<intersection>/` per run and
/// `<out>/summary.txt` and `<out>/summary.json`.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "traffic/nema/collision_oracle.h"

namespace autodrive::traffic::nema {

/// What to run.
struct CollisionBatchOptions {
  std::filesystem::path program;  ///< the autodrive-scm-nema executable each run is
  std::filesystem::path city;     ///< the city file
  /// The runs' options (`out_dir`: DIR; `intersection` and `progress` are ignored).
  CollisionOracleOptions oracle;
  std::vector<std::string> intersections;  ///< one run each (the city's signalised ones)
  /// How long one run may take before it is stopped (wall time).
  std::chrono::milliseconds run_timeout = std::chrono::minutes(30);
  /// Called with a line as each run starts and ends.
  std::function<void(const std::string&)> progress;
};

/// What one intersection's run gave (from its report.json).
struct IntersectionRun {
  std::string intersection;
  std::filesystem::path dir;
  int exit_code = -1;  ///< the child's: 0 none, 1 junction collisions, 2 bad input, 3 SUMO failed
  bool ran = false;    ///< it wrote a report
  std::string error;   ///< why it did not run (the child's output), when it did not
  int junction_collisions = 0;
  int intergreen_collisions = 0;  ///< of them, between vehicles of conflicting groups
  int other_collisions = 0;
  std::int64_t vehicles_departed = 0;
  std::uint64_t monitor_violations = 0;
  double cpu_s = 0.0;   ///< the child's CPU time for its run
  double wall_s = 0.0;  ///< informative
};

/// What the batch found; the summary is also written to `<out>/summary.txt` and `.json`.
struct CollisionBatchResult {
  std::vector<IntersectionRun> runs;
  int junction_collisions = 0;  ///< over all runs
  int failed = 0;               ///< runs that did not run
  std::string text;
  std::filesystem::path text_summary, json_summary;
};

/// Runs the batch. Throws `InputError` for bad options (no intersections, no program or output
/// folder); a run that fails is recorded, not thrown.
[[nodiscard]] CollisionBatchResult RunCollisionBatch(const CollisionBatchOptions& options);

/// The command line that runs (or replays) `intersection`'s run of `options` into `dir`.
[[nodiscard]] std::vector<std::string> CollisionCommand(const CollisionBatchOptions& options,
                                                        const std::string& intersection,
                                                        const std::filesystem::path& dir);

}  // namespace autodrive::traffic::nema
