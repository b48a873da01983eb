#pragma once
/// @file
/// A sweep (`autodrive-scenario sweep`): one scenario run over a list or grid of seeds and
/// variants (scenario parameters, agent arguments), several runs at once on this machine, each
/// run an `autodrive-scenario run` process of its own (its own DDS partition); a progress bar,
/// resume where it stopped (a run with its report.json is done), and one summary of every
/// metric per variant (docs/scenarios.md, "Sweeps").
///
/// ```yaml
/// name: crossing_seeds
/// scenario: ../config/scenarios/small_town_crossing.yaml
/// seed_range: {first: 1, count: 10}  # or a list: seeds: [1, 2, 3]
/// parallel: 2
/// variants:
///   - name: driver
///   - name: slow
///     agent_args: [--throttle, "0.4"]     # added to every car's example driver
///     set: {time_limit_s: 90}            # scenario keys replaced
/// ```

#include <yaml-cpp/yaml.h>

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config.h"

namespace autodrive::scenarios {

struct SeedRange {
  std::uint64_t first = 1;
  int count = 1;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("first", first);
    a.Required("count", count, config::Range{1, 1000000});
  }
  bool operator==(const SeedRange&) const = default;
};

struct VariantSpec {
  std::string name;
  /// Arguments added to the example driver of every car whose agent is `driver`.
  std::vector<std::string> agent_args;
  /// Top-level scenario keys replaced (e.g. `time_limit_s`, `traffic`, `noise`, `expect`),
  /// as YAML; the result is checked as a scenario file.
  std::map<std::string, config::ForeignSection> set;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("agent_args", agent_args);
    a.Optional("set", set);
  }
  bool operator==(const VariantSpec&) const = default;
};

struct SweepSpec {
  std::string name;
  std::string scenario;  ///< relative to the sweep file
  std::vector<std::uint64_t> seeds;
  std::optional<SeedRange> seed_range;  ///< `seeds: {first, count}` is read into this
  std::vector<VariantSpec> variants{VariantSpec{"default", {}, {}}};
  int parallel = 2;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("scenario", scenario);
    a.Optional("seeds", seeds);
    a.Optional("seed_range", seed_range);
    a.Optional("variants", variants);
    a.Optional("parallel", parallel, config::Range{1, 256});
  }
  /// A plain name; seeds given one way; variant names plain and unique.
  void Validate() const;
  bool operator==(const SweepSpec&) const = default;
};

/// One run of a sweep.
struct SweepRun {
  std::string id;  ///< `<variant>_seed<N>`: its folder under `runs/`
  std::string variant;
  std::uint64_t seed = 1;
};

/// Loads a sweep file. @throws ConfigError naming the file, line and key.
[[nodiscard]] SweepSpec LoadSweep(const std::filesystem::path& path);
/// Every run of the sweep, variant by variant, seed by seed.
[[nodiscard]] std::vector<SweepRun> PlanSweep(const SweepSpec& sweep);
/// The scenario file of `variant` (the sweep's scenario with its changes), as text.
/// @throws ConfigError when the result is not a valid scenario.
[[nodiscard]] std::string VariantScenario(const SweepSpec& sweep,
                                          const std::filesystem::path& sweep_file,
                                          const VariantSpec& variant);

struct SweepOptions {
  std::filesystem::path sweep_file;
  std::filesystem::path out_dir;
  std::filesystem::path bin_dir;
  std::optional<int> parallel;  ///< overrides the file's
  bool resume = false;          ///< keep finished runs (otherwise a non-empty folder is refused)
  const std::atomic<bool>* stop = nullptr;
  bool progress = true;  ///< a progress bar on stderr
  /// Submit the runs as a Slurm array job (one run per task) instead of running them here,
  /// follow it with the same progress bar and summarise; `slurm_args` go to `sbatch`.
  bool slurm = false;
  std::vector<std::string> slurm_args;
};

struct SweepResult {
  int done = 0;     ///< runs with a report (this time or before)
  int failed = 0;   ///< of them, runs that could not be made (exit code 2)
  int skipped = 0;  ///< finished before (resume)
  int left = 0;     ///< not run (interrupted)
  nlohmann::json summary;
};

/// Runs the sweep into `out_dir` (sweep.yaml copied, runs/<id>/, summary.json). @throws
/// ConfigError / InputError for a bad sweep or scenario before any run starts.
[[nodiscard]] SweepResult RunSweep(const SweepOptions& options);

/// The summary of the runs in `out_dir` (every run's report.json that exists): per variant,
/// each run's run metrics and their n, mean, standard deviation, min, max and worst.
[[nodiscard]] nlohmann::json SummariseSweep(const SweepSpec& sweep,
                                            const std::filesystem::path& sweep_file,
                                            const std::filesystem::path& out_dir);

}  // namespace autodrive::scenarios
