#include "scenarios/sweep.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <set>
#include <thread>

#include "scenarios/report_html.h"
#include "scenarios/scenario.h"

#include "common/error.h"
#include "common/process.h"
#include "common/shutdown.h"

namespace autodrive::scenarios {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

bool IsPlainName(const std::string& s) {
  return !s.empty() && s.find_first_not_of(
                           "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                           "0123456789_-") == std::string::npos;
}

// Metrics where a larger value is better (the worst is the smallest).
bool HigherIsBetter(const std::string& metric) {
  static const std::set<std::string> higher{
      "route_completion", "goals_reached",    "score",      "spat_messages",
      "map_messages",     "requests_granted", "distance_m", "background_trips"};
  return higher.contains(metric);
}

// A run is finished when its report.json exists and says it ran (not interrupted).
bool Finished(const fs::path& run_dir) {
  std::ifstream in(run_dir / "report.json");
  if (!in) return false;
  try {
    const json report = json::parse(in);
    return report.at("end").at("reason") != "interrupted";
  } catch (const std::exception&) {
    return false;
  }
}

void ProgressBar(int done, int failed, int left, int running, int total) {
  const int width = 30;
  const int filled = total > 0 ? width * done / total : width;
  std::fprintf(stderr, "\r[%s%s] %d/%d done, %d failed, %d left (%d running)  ",
               std::string(static_cast<std::size_t>(filled), '#').c_str(),
               std::string(static_cast<std::size_t>(width - filled), '.').c_str(), done, total,
               failed, left, running);
  std::fflush(stderr);
}

// A word for a bash script, single-quoted.
std::string Quote(const std::string& word) {
  std::string out = "'";
  for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Runs a command, returning its exit code and standard output.
std::pair<int, std::string> Capture(const std::vector<std::string>& argv) {
  ChildProcess p(argv);
  std::string out;
  while (auto line = p.ReadLine(std::chrono::milliseconds(120'000))) out += *line + "\n";
  return {p.Wait(std::chrono::milliseconds(60'000)).value_or(-1), out};
}

// The Slurm array job of the runs `todo` (indices into `runs`): its script in OUT/slurm/.
std::string ArrayScript(const SweepSpec& sweep, const std::vector<SweepRun>& runs,
                        const std::vector<std::size_t>& todo, const fs::path& out,
                        const fs::path& bin) {
  std::string ids, variants, seeds, indices;
  for (const SweepRun& r : runs) {
    ids += " " + Quote(r.id);
    variants += " " + Quote(r.variant);
    seeds += " " + std::to_string(r.seed);
  }
  for (const std::size_t i : todo) indices += (indices.empty() ? "" : ",") + std::to_string(i);
  return fmt::format(
      "#!/bin/bash\n"
      "# Sweep {name}: one scenario run per array task (autodrive-scenario sweep --slurm).\n"
      "#SBATCH --job-name=autodrive-sweep-{name}\n"
      "#SBATCH --output={out}/slurm/%A_%a.out\n"
      "#SBATCH --array={indices}\n"
      "#SBATCH --ntasks=1\n"
      "set -euo pipefail\n"
      "ids=({ids})\n"
      "variants=({variants})\n"
      "seeds=({seeds})\n"
      "i=$SLURM_ARRAY_TASK_ID\n"
      "mkdir -p {out_q}/runs/\"${{ids[$i]}}\"\n"
      "exec {bin} run {out_q}/variants/\"${{variants[$i]}}.yaml\" --out "
      "{out_q}/runs/\"${{ids[$i]}}\" "
      "--seed \"${{seeds[$i]}}\" --quiet\n",
      fmt::arg("name", sweep.name), fmt::arg("out", out.string()),
      fmt::arg("out_q", Quote(out.string())), fmt::arg("indices", indices), fmt::arg("ids", ids),
      fmt::arg("variants", variants), fmt::arg("seeds", seeds),
      fmt::arg("bin", Quote((bin / "autodrive-scenario").string())));
}

}  // namespace

void SweepSpec::Validate() const {
  if (!IsPlainName(name)) {
    throw InputError(fmt::format("name: \"{}\" (letters, digits, '_' and '-' only)", name));
  }
  if (!seeds.empty() && seed_range) throw InputError("give seeds or seed_range, not both");
  std::set<std::string> names;
  for (const VariantSpec& v : variants) {
    if (!IsPlainName(v.name)) {
      throw InputError(
          fmt::format("variants: name \"{}\" (letters, digits, '_' and '-' only)", v.name));
    }
    if (!names.insert(v.name).second) {
      throw InputError(fmt::format("variants: {} is listed twice", v.name));
    }
  }
  if (variants.empty()) throw InputError("variants: at least one");
}

SweepSpec LoadSweep(const fs::path& path) {
  SweepSpec s = config::LoadFile<SweepSpec>(path);
  const fs::path scenario = fs::absolute(path).parent_path() / s.scenario;
  if (!fs::exists(scenario)) {
    throw ConfigError(LocateInFile(path, {"scenario"}, scenario.string() + " does not exist"));
  }
  s.scenario = scenario.lexically_normal().string();
  return s;
}

std::vector<SweepRun> PlanSweep(const SweepSpec& sweep) {
  std::vector<std::uint64_t> seeds = sweep.seeds;
  if (sweep.seed_range) {
    for (int i = 0; i < sweep.seed_range->count; ++i) {
      seeds.push_back(sweep.seed_range->first + static_cast<std::uint64_t>(i));
    }
  }
  if (seeds.empty()) seeds.push_back(1);
  std::vector<SweepRun> runs;
  for (const VariantSpec& v : sweep.variants) {
    for (const std::uint64_t seed : seeds) {
      runs.push_back({fmt::format("{}_seed{}", v.name, seed), v.name, seed});
    }
  }
  return runs;
}

std::string VariantScenario(const SweepSpec& sweep, const fs::path& sweep_file,
                            const VariantSpec& variant) {
  YAML::Node root = YAML::LoadFile(sweep.scenario);
  // The city relative to the scenario's own folder, so that the file works anywhere.
  root["city"] = (fs::path(sweep.scenario).parent_path() / root["city"].as<std::string>())
                     .lexically_normal()
                     .string();
  for (const auto& [key, value] : variant.set) root[key] = YAML::Load(value.yaml);
  if (!variant.agent_args.empty()) {
    for (auto v : root["vehicles"]) {
      if (v["agent"] && v["agent"]["driver"]) {
        for (const std::string& arg : variant.agent_args) v["agent"]["driver"].push_back(arg);
      }
    }
  }
  YAML::Emitter out;
  out << root;
  const std::string text =
      fmt::format("# Sweep {} ({}), variant {}: {} with its changes.\n{}\n", sweep.name,
                  fs::absolute(sweep_file).lexically_normal().string(), variant.name,
                  sweep.scenario, out.c_str());
  try {
    (void)config::LoadString<Scenario>(text, sweep.scenario + " (variant " + variant.name + ")");
  } catch (const ConfigError& e) {
    throw ConfigError(LocateInFile(sweep_file, {"variants"},
                                   fmt::format("variant {}: {}", variant.name, e.what())));
  }
  return text;
}

json SummariseSweep(const SweepSpec& sweep, const fs::path& sweep_file, const fs::path& out_dir) {
  const std::vector<SweepRun> runs = PlanSweep(sweep);
  json summary;
  summary["sweep"] = {{"name", sweep.name},
                      {"file", fs::absolute(sweep_file).lexically_normal().string()},
                      {"scenario", sweep.scenario}};
  json metrics = json::array();
  for (const auto m : RunMetricNames()) metrics.push_back(std::string(m));
  summary["metrics"] = metrics;
  int done = 0, failed = 0;
  json variants = json::array();
  for (const VariantSpec& v : sweep.variants) {
    json runs_json = json::array();
    std::map<std::string, std::vector<double>> values;
    for (const SweepRun& r : runs) {
      if (r.variant != v.name) continue;
      const fs::path report_file = out_dir / "runs" / r.id / "report.json";
      std::ifstream in(report_file);
      if (!in) continue;
      json report;
      try {
        report = json::parse(in);
      } catch (const json::exception& e) {
        throw InputError(fmt::format("{}: {}", report_file.string(), e.what()));
      }
      ++done;
      const bool made = report["end"]["reason"] != "failed";
      if (!made) ++failed;
      json m = json::object();
      for (const auto name : RunMetricNames()) {
        const json& value = report["metrics"]["run"][std::string(name)];
        m[std::string(name)] = value;
        if (made && value.is_number()) values[std::string(name)].push_back(value.get<double>());
      }
      runs_json.push_back({{"id", r.id},
                           {"seed", r.seed},
                           {"passed", report["passed"]},
                           {"end", report["end"]["reason"]},
                           {"report", "runs/" + r.id + "/report.json"},
                           {"metrics", m}});
    }
    json stats = json::object();
    for (const auto name_view : RunMetricNames()) {
      const std::string name(name_view);
      const std::vector<double>& x = values[name];
      if (x.empty()) {
        stats[name] = {{"n", 0}};
        continue;
      }
      double sum = 0;
      for (double y : x) sum += y;
      const double mean = sum / static_cast<double>(x.size());
      double ss = 0;
      for (double y : x) ss += (y - mean) * (y - mean);
      const double std = x.size() > 1 ? std::sqrt(ss / static_cast<double>(x.size() - 1)) : 0.0;
      const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
      const auto round6 = [](double y) { return std::round(y * 1e6) / 1e6; };
      stats[name] = {{"n", x.size()},      {"mean", round6(mean)},
                     {"std", round6(std)}, {"min", round6(*lo)},
                     {"max", round6(*hi)}, {"worst", round6(HigherIsBetter(name) ? *lo : *hi)}};
    }
    variants.push_back({{"name", v.name},
                        {"parameters", {{"agent_args", v.agent_args}}},
                        {"runs", runs_json},
                        {"stats", stats}});
    for (const auto& [key, value] : v.set) variants.back()["parameters"][key] = value.yaml;
  }
  summary["variants"] = variants;
  summary["runs_total"] = runs.size();
  summary["runs_done"] = done;
  summary["runs_failed"] = failed;
  return summary;
}

SweepResult RunSweep(const SweepOptions& options) {
  const SweepSpec sweep = LoadSweep(options.sweep_file);
  const fs::path out = fs::absolute(options.out_dir).lexically_normal();
  if (fs::exists(out / "runs") && !options.resume && !fs::is_empty(out / "runs")) {
    throw InputError(
        fmt::format("{} holds runs of an earlier sweep: --resume to finish it, or another --out",
                    out.string()));
  }
  fs::create_directories(out / "runs");
  fs::create_directories(out / "variants");
  fs::copy_file(options.sweep_file, out / "sweep.yaml", fs::copy_options::overwrite_existing);
  // Each variant's scenario, checked before anything runs.
  std::map<std::string, fs::path> scenario_of;
  for (const VariantSpec& v : sweep.variants) {
    const fs::path file = out / "variants" / (v.name + ".yaml");
    config::WriteFile(file, VariantScenario(sweep, options.sweep_file, v));
    scenario_of[v.name] = file;
  }
  const std::vector<SweepRun> runs = PlanSweep(sweep);
  const int parallel = options.parallel.value_or(sweep.parallel);
  const int total = static_cast<int>(runs.size());

  SweepResult result;
  std::vector<const SweepRun*> todo;
  for (const SweepRun& r : runs) {
    if (options.resume && Finished(out / "runs" / r.id)) {
      ++result.skipped;
      ++result.done;
    } else {
      todo.push_back(&r);
    }
  }
  const auto stopping = [&] { return options.stop != nullptr && options.stop->load(); };
  if (options.slurm) {
    std::vector<std::size_t> indices;
    for (const SweepRun* r : todo) indices.push_back(static_cast<std::size_t>(r - runs.data()));
    const auto count_done = [&] {
      int n = 0;
      for (const SweepRun& r : runs) n += Finished(out / "runs" / r.id) ? 1 : 0;
      return n;
    };
    if (!indices.empty()) {
      fs::create_directories(out / "slurm");
      const fs::path script = out / "slurm" / "array.sh";
      config::WriteFile(script, ArrayScript(sweep, runs, indices, out, options.bin_dir));
      std::vector<std::string> argv{"sbatch", "--parsable"};
      argv.insert(argv.end(), options.slurm_args.begin(), options.slurm_args.end());
      argv.push_back(script.string());
      const auto [code, said] = Capture(argv);
      if (code != 0) {
        throw InputError(
            fmt::format("sbatch {} failed (exit code {}): {}", script.string(), code, said));
      }
      const std::string job = said.substr(0, said.find_first_of(";\n"));
      config::WriteFile(out / "slurm" / "job_id", job + "\n");
      if (options.progress)
        std::fprintf(stderr, "submitted Slurm array job %s (%zu tasks)\n", job.c_str(),
                     indices.size());
      // Follow it: the runs' reports, until the job has left the queue.
      while (true) {
        const auto [qcode, queue] = Capture({"squeue", "-h", "-j", job, "-o", "%i"});
        const int finished = count_done();
        if (options.progress) {
          ProgressBar(finished, 0, total - finished, 0, total);
        }
        if (stopping()) {
          (void)Capture({"scancel", job});
          break;
        }
        if (qcode == 0 && queue.find_first_not_of(" \n") == std::string::npos) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
      }
      if (options.progress) std::fprintf(stderr, "\n");
    }
    result.done = count_done();
    result.left = total - result.done;
    result.summary = SummariseSweep(sweep, options.sweep_file, out);
    result.failed = result.summary["runs_failed"].get<int>();
    config::WriteFile(out / "summary.json", result.summary.dump(2) + "\n");
    config::WriteFile(out / "summary.html", SummaryHtml(result.summary));
    return result;
  }
  struct Running {
    const SweepRun* run;
    ChildProcess child;
  };
  std::vector<Running> running;
  std::size_t next = 0;
  const auto draw = [&] {
    if (options.progress) {
      ProgressBar(result.done, result.failed,
                  total - result.done - static_cast<int>(running.size()),
                  static_cast<int>(running.size()), total);
    }
  };
  draw();
  while ((next < todo.size() && !stopping()) || !running.empty()) {
    while (!stopping() && next < todo.size() && static_cast<int>(running.size()) < parallel) {
      const SweepRun& r = *todo[next++];
      const fs::path dir = out / "runs" / r.id;
      fs::create_directories(dir);
      ChildOptions child;
      child.output_file = dir / "runner.log";
      child.extra_env = {fmt::format("{}={}", kStopWithParentEnv, getpid())};
      running.push_back(
          {&r, ChildProcess::Start({(options.bin_dir / "autodrive-scenario").string(), "run",
                                    scenario_of[r.variant].string(), "--out", dir.string(),
                                    "--seed", std::to_string(r.seed), "--quiet"},
                                   child)});
      draw();
    }
    bool any = false;
    for (auto it = running.begin(); it != running.end();) {
      const std::optional<int> code = it->child.Wait(std::chrono::milliseconds(0));
      if (!code) {
        ++it;
        continue;
      }
      any = true;
      if (*code != 130) {
        ++result.done;
        if (*code != 0 && *code != 1) ++result.failed;
      }
      it = running.erase(it);
      draw();
    }
    if (stopping()) {
      // Ctrl-C: each run takes its city down (SIGTERM) and says it was interrupted.
      for (Running& r : running) (void)r.child.Stop(std::chrono::seconds(60));
      running.clear();
      break;
    }
    if (!any) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  result.left = total - result.done;
  if (options.progress) {
    draw();
    std::fprintf(stderr, "\n");
  }
  result.summary = SummariseSweep(sweep, options.sweep_file, out);
  config::WriteFile(out / "summary.json", result.summary.dump(2) + "\n");
  config::WriteFile(out / "summary.html", SummaryHtml(result.summary));
  return result;
}

}  // namespace autodrive::scenarios
