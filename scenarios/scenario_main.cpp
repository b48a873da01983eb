// autodrive-scenario: runs a scenario of the twin in lockstep and judges it from ground truth,
// lamps and SPaT (docs/scenarios.md).
#include <atomic>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "scenarios/report_html.h"
#include "scenarios/runner.h"
#include "scenarios/sweep.h"

#include "common/config.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/process.h"
#include "common/shutdown.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  CLI::App app{
      "autodrive-scenario: runs scenarios of the twin (a city, cars and the programs that drive "
      "them, events, pass thresholds) in lockstep, and judges each run from the simulator's "
      "ground truth, the lamps and SPaT. See docs/scenarios.md."};
  app.require_subcommand(1);
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();

  scenarios::RunOptions run;
  std::uint64_t seed = 0;
  CLI::App* run_cmd = app.add_subcommand(
      "run",
      "run one scenario: bring its city up in lockstep, record, apply its events, take it "
      "down, and write report.json and report.html in --out. Exit code 0: every expectation "
      "held; 1: one failed; 2: the run could not be made; 130: interrupted");
  std::string scenario_file, out_dir;
  run_cmd->add_option("scenario", scenario_file, "the scenario file (YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  run_cmd
      ->add_option("--out", out_dir, "the run folder (made; what an earlier run left is replaced)")
      ->required();
  CLI::Option* seed_opt =
      run_cmd->add_option("--seed", seed, "the seed, instead of the scenario's");
  run_cmd->add_option("--partition", run.partition,
                      "DDS partition of the run (default: one of its own, so that runs beside "
                      "each other and a running city never meet)");
  bool quiet = false;
  run_cmd->add_flag("--quiet", quiet, "no progress lines");
  run_cmd->add_flag("--record", run.record,
                    "keep the run's topics in recording.mcap in the run folder (rosbag2-compatible "
                    "MCAP, cameras aside; docs/recording.md)");

  scenarios::SweepOptions sweep;
  CLI::App* sweep_cmd = app.add_subcommand(
      "sweep",
      "run a scenario over seeds and variants, several runs at once, with a progress bar; "
      "--resume finishes a sweep that was stopped without running its finished runs again. "
      "Writes runs/<variant>_seed<N>/ and summary.json in --out. Exit code 0: every run was "
      "made (whatever its expectations); 2: a run could not be made; 130: interrupted");
  std::string sweep_file, sweep_out;
  int parallel = 0;
  sweep_cmd->add_option("sweep", sweep_file, "the sweep file (YAML)")
      ->required()
      ->check(CLI::ExistingFile);
  sweep_cmd->add_option("--out", sweep_out, "the sweep folder")->required();
  sweep_cmd->add_option("--parallel", parallel, "runs at once (default: the file's, else 2)")
      ->check(CLI::Range(1, 256));
  sweep_cmd->add_flag("--resume", sweep.resume,
                      "finish a sweep in --out: keep its finished runs, run the rest");
  sweep_cmd->add_flag("--quiet", quiet, "no progress bar");
  sweep_cmd->add_flag("--slurm", sweep.slurm,
                      "submit the runs as a Slurm array job (one run per task; --out on storage "
                      "every node sees), follow it and summarise; with --resume, only the runs "
                      "not finished are submitted");
  sweep_cmd->add_option("--slurm-arg", sweep.slurm_args,
                        "an argument for sbatch (repeat: --slurm-arg=--partition=lab "
                        "--slurm-arg=--time=30)");

  // Re-rendering the pages (e.g. after an update of the reports): from the files only.
  std::string render_in, render_out;
  CLI::App* report_cmd = app.add_subcommand(
      "render-report", "write a run folder's report.html again from its report.json and logs/");
  report_cmd->add_option("run", render_in, "the run folder")
      ->required()
      ->check(CLI::ExistingDirectory);
  CLI::App* summary_cmd = app.add_subcommand(
      "render-summary",
      "write a sweep's summary.html from its summary.json (write it beside summary.json: the "
      "links to the runs' reports are relative to it)");
  summary_cmd->add_option("summary", render_in, "summary.json")
      ->required()
      ->check(CLI::ExistingFile);
  summary_cmd->add_option("file", render_out, "the page to write")->required();
  CLI11_PARSE(app, argc, argv);

  if (report_cmd->parsed() || summary_cmd->parsed()) {
    const auto read_json = [](const std::filesystem::path& file) {
      try {
        return nlohmann::json::parse(config::ReadFile(file));
      } catch (const nlohmann::json::exception& e) {
        throw InputError(file.string() + ": " + e.what());
      }
    };
    try {
      if (report_cmd->parsed()) {
        const std::filesystem::path dir = render_in;
        const auto report = read_json(dir / "report.json");
        config::WriteFile(dir / "report.html", scenarios::ReportHtml(report, dir));
        std::printf("%s\n", (dir / "report.html").string().c_str());
      } else {
        const auto summary = read_json(render_in);
        config::WriteFile(render_out, scenarios::SummaryHtml(summary));
        std::printf("%s\n", render_out.c_str());
      }
      return 0;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "autodrive-scenario: %s\n", e.what());
      return 2;
    }
  }

  try {
    InitLogging("autodrive-scenario", ParseLogLevel(log_level));
    std::atomic<bool> stop{false};
    ShutdownSignals signals([&] { stop.store(true); });
    StopWithParentIfAsked();
    if (*sweep_cmd) {
      sweep.sweep_file = sweep_file;
      sweep.out_dir = sweep_out;
      sweep.bin_dir = ExecutableDir();
      if (parallel > 0) sweep.parallel = parallel;
      sweep.stop = &stop;
      sweep.progress = !quiet;
      const scenarios::SweepResult r = scenarios::RunSweep(sweep);
      std::printf(
          "%s: %d of %d runs done (%d before), %d could not be made, %d left; summary: "
          "%s/summary.json\n",
          r.summary["sweep"]["name"].get<std::string>().c_str(), r.done,
          r.summary["runs_total"].get<int>(), r.skipped, r.failed, r.left, sweep_out.c_str());
      if (stop.load()) return 130;
      return r.failed > 0 ? 2 : 0;
    }
    run.scenario_file = scenario_file;
    run.out_dir = out_dir;
    run.bin_dir = ExecutableDir();
    if (seed_opt->count() > 0) run.seed = seed;
    run.command_line.assign(argv, argv + argc);
    run.stop = &stop;
    run.progress = !quiet;
    const scenarios::RunResult result = scenarios::RunScenario(run);
    const auto& end = result.report["end"];
    std::printf("%s: %s at %.2f s (%s); report: %s/report.json\n",
                result.report["scenario"]["name"].get<std::string>().c_str(),
                result.exit_code == 0   ? "passed"
                : result.exit_code == 1 ? "FAILED"
                                        : "not completed",
                end["t_s"].get<double>(), end["reason"].get<std::string>().c_str(),
                out_dir.c_str());
    for (const std::string& f : result.failures) std::printf("  failed: %s\n", f.c_str());
    return result.exit_code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-scenario: %s\n", e.what());
    return 2;
  }
}
