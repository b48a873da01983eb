#pragma once
/// @file
/// The crosscheck over many seeded random call scripts (`autodrive-scm-nema crosscheck-random`):
/// each seed runs as a child process of the program (`crosscheck --random-calls SEED
/// --compare sequence`; libsumo runs one simulation per process), and the batch writes a summary
/// of how many seeds matched and, for each that did not, its differences with the rule behind
/// each (diagnosis.h), the evidence and the setting that removes it
/// (docs/controller-crosscheck.md).

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "common/time.h"

namespace autodrive::traffic::nema {

/// What to run.
struct RandomBatchOptions {
  std::filesystem::path program;  ///< the autodrive-scm-nema executable each seed runs
  std::filesystem::path city;     ///< the city file
  std::string intersection;
  std::string plan;
  int seeds = 20;                ///< how many seeds, from `first_seed` on
  std::uint64_t first_seed = 1;  ///< the first seed
  Duration duration = std::chrono::seconds(900);
  Duration tolerance = std::chrono::milliseconds(200);
  Duration mean_gap = std::chrono::seconds(20);  ///< RandomCallParams::mean_gap
  Duration calls_from{0};                        ///< RandomCallParams::calls_from
  /// Seeds that must match for the batch to pass (at most `seeds`).
  int required = 20;
  std::filesystem::path out_dir;  ///< DIR: DIR/seed-<n>/ per seed, DIR/summary.{txt,json}
  /// How long one seed may run before it is stopped (wall time).
  std::chrono::milliseconds seed_timeout = std::chrono::minutes(10);
};

/// One stretch of differences of a seed, as its report gives it.
struct SeedDifference {
  std::string text;  ///< where the sequences part and rejoin
  std::string rule, summary, evidence, remedy;
};

/// What one seed gave.
struct SeedOutcome {
  std::uint64_t seed = 0;
  std::filesystem::path dir;
  int exit_code = -1;  ///< the child's: 0 match, 1 different, 2 bad input, 3 SUMO failed
  bool ran = false;    ///< it wrote a report
  bool matched = false;
  std::string error;  ///< why it did not run (the child's output), when it did not
  std::size_t calls = 0;
  std::size_t intervals = 0;  ///< our intervals compared in sequence
  double max_difference_s = 0.0;
  std::vector<SeedDifference> differences;  ///< in time order; the first is the first difference
  double wall_s = 0.0;                      ///< wall time of the child (informative)
};

/// What the batch found; the summary is also written to `<out>/summary.txt` and `.json`.
struct RandomBatchResult {
  std::vector<SeedOutcome> seeds;
  int matched = 0;
  int failed = 0;       ///< seeds that did not run
  bool passed = false;  ///< matched >= required and none failed
  /// Per rule: how many seeds it was the first difference of, and how many stretches it
  /// explains in all.
  std::map<std::string, std::pair<int, int>> rules;
  std::string text;
  std::filesystem::path text_summary, json_summary;
};

/// Runs the batch. Throws `InputError` for bad options (no seeds, more required than seeds, no
/// program or output folder); a seed that fails to run is recorded, not thrown.
[[nodiscard]] RandomBatchResult RunRandomBatch(const RandomBatchOptions& options);

/// The command line that runs (or replays) `seed` of `options` into `dir`.
[[nodiscard]] std::vector<std::string> SeedCommand(const RandomBatchOptions& options,
                                                   std::uint64_t seed,
                                                   const std::filesystem::path& dir);

}  // namespace autodrive::traffic::nema
