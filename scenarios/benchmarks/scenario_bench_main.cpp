// autodrive-bench-scenario: what a scenario run costs. The wall time of one run of a scenario
// (by default the small town's crossing: 60 simulated seconds, four cars, SUMO) as a ratio to
// its simulated time, and the runner's own overhead: the same composed city run by
// `autodrive-city up` alone (no runner, no recording, no metrics) against the whole run. Both
// run to the time limit (the end at the goals is turned off), on the CPUs given (default: all).
#include <fmt/format.h>
#include <sched.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "scenarios/runner.h"

#include "common/config.h"
#include "common/logging.h"
#include "common/process.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  namespace fs = std::filesystem;
  CLI::App app{
      "autodrive-bench-scenario: wall time of a scenario run against its simulated time, and "
      "the runner's overhead over the same city run by autodrive-city alone"};
  std::string scenario;
  std::string work = (fs::temp_directory_path() / "autodrive-bench-scenario").string();
  std::string cpus;
  int rounds = 1;
  app.add_option("--scenario", scenario,
                 "the scenario (default: config/scenarios/small_town_crossing.yaml)");
  app.add_option("--work-dir", work, "where the runs go")->capture_default_str();
  app.add_option("--cpus", cpus, "run on these CPUs only, e.g. 0 (one core) or 0,1");
  app.add_option("--rounds", rounds, "pairs of runs (alternating)")->check(CLI::Range(1, 20));
  CLI11_PARSE(app, argc, argv);
  try {
    InitLogging("autodrive-bench-scenario", spdlog::level::warn);
    const fs::path bin = ExecutableDir();
    if (scenario.empty()) {
      scenario = (bin / ".." / ".." / "config/scenarios/small_town_crossing.yaml")
                     .lexically_normal()
                     .string();
    }
    if (!cpus.empty()) {
      cpu_set_t set;
      CPU_ZERO(&set);
      std::size_t at = 0;
      while (at <= cpus.size()) {
        const std::size_t comma = std::min(cpus.find(',', at), cpus.size());
        CPU_SET(static_cast<std::size_t>(std::stoul(cpus.substr(at, comma - at))), &set);
        at = comma + 1;
      }
      if (sched_setaffinity(0, sizeof set, &set) != 0) throw InputError("--cpus: cannot set them");
    }
    fs::remove_all(work);
    fs::create_directories(work);
    // The scenario, run to its time limit.
    YAML::Node s = YAML::LoadFile(scenario);
    s["city"] = (fs::absolute(scenario).parent_path() / s["city"].as<std::string>())
                    .lexically_normal()
                    .string();
    s["end"]["goals_reached"] = false;
    YAML::Emitter e;
    e << s;
    const fs::path file = fs::path(work) / "scenario.yaml";
    config::WriteFile(file, e.c_str());
    double sim_s = 0, with_sum = 0, alone_sum = 0;
    for (int round = 0; round < rounds; ++round) {
      scenarios::RunOptions run;
      run.scenario_file = file;
      run.out_dir = fs::path(work) / fmt::format("run{}", round);
      run.bin_dir = bin;
      run.progress = false;
      const auto t0 = std::chrono::steady_clock::now();
      const scenarios::RunResult r = scenarios::RunScenario(run);
      const double with_runner =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      sim_s = r.report["end"]["t_s"].get<double>();
      // The same city without the runner: its controller and its place in the launch removed.
      YAML::Node city = YAML::LoadFile((run.out_dir / "city.yaml").string());
      YAML::Node controllers(YAML::NodeType::Sequence);
      for (const auto& c : city["sim"]["service"]["controllers"]) {
        if (c.as<std::string>() != "scenario") controllers.push_back(c);
      }
      city["sim"]["service"]["controllers"] = controllers;
      city["launch"].remove("external_controllers");
      city["launch"]["run_dir"] = (fs::path(work) / fmt::format("alone{}", round)).string();
      YAML::Emitter ce;
      ce << city;
      const fs::path alone_file = fs::path(work) / fmt::format("alone{}.yaml", round);
      config::WriteFile(alone_file, ce.c_str());
      ChildOptions options;
      options.extra_env = {"TZ=UTC"};
      options.output_file = fs::path(work) / fmt::format("alone{}.log", round);
      const auto t1 = std::chrono::steady_clock::now();
      ChildProcess up =
          ChildProcess::Start({(bin / "autodrive-city").string(), "up", alone_file.string(),
                               "--partition", fmt::format("bench_scenario_{}_{}", getpid(), round)},
                              options);
      const std::optional<int> code = up.Wait(std::chrono::minutes(30));
      const double alone =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
      if (code != 0)
        throw InputError("the city alone did not end cleanly: see " + options.output_file.string());
      std::printf(
          "round %d: %.2f simulated s; scenario run %.2f s wall (%.2fx real time, %s); "
          "city alone %.2f s (%.2fx); runner overhead %.3fx\n",
          round + 1, sim_s, with_runner, sim_s / with_runner,
          r.report["passed"].get<bool>() ? "passed" : "failed", alone, sim_s / alone,
          with_runner / alone);
      with_sum += with_runner;
      alone_sum += alone;
    }
    std::printf(
        "mean: scenario %.2fx real time (goal >= 2x), runner overhead %.3fx (goal <= 1.1x)%s\n",
        sim_s * rounds / with_sum, with_sum / alone_sum,
        cpus.empty() ? "" : (" on CPUs " + cpus).c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-bench-scenario: %s\n", e.what());
    return 1;
  }
}
