#include "traffic/nema/collision_batch.h"

#include <fmt/format.h>

#include <optional>

#include <nlohmann/json.hpp>

#include "traffic/nema/internal/child_run.h"
#include "traffic/nema/internal/io.h"
#include "traffic/nema/nema_program.h"

#include "common/error.h"

namespace autodrive::traffic::nema {

namespace {

namespace fs = std::filesystem;
using internal::Quoted;
using internal::ReadFile;
using internal::WriteFile;

// The run's report.json into `r`.
void ReadReport(const fs::path& file, IntersectionRun& r) {
  const nlohmann::json j = nlohmann::json::parse(ReadFile(file));
  r.junction_collisions = j.at("junction_collisions").get<int>();
  r.intergreen_collisions = j.at("intergreen_collisions").get<int>();
  r.other_collisions = j.at("other_collisions").get<int>();
  r.vehicles_departed = j.at("vehicles_departed").get<std::int64_t>();
  r.monitor_violations = j.at("monitor_violations").get<std::uint64_t>();
  r.cpu_s = j.at("cpu_s").get<double>();
}

IntersectionRun Run(const CollisionBatchOptions& o, const std::string& intersection,
                    const fs::path& out) {
  IntersectionRun r;
  r.intersection = intersection;
  r.dir = out / intersection;
  const internal::ChildRun run =
      internal::RunChild(CollisionCommand(o, intersection, r.dir), r.dir, o.run_timeout,
                         [&](const fs::path& report) { ReadReport(report, r); });
  r.exit_code = run.exit_code;
  r.ran = run.ran;
  r.error = run.error;
  r.wall_s = run.wall_s;
  return r;
}

std::string RunLine(const IntersectionRun& r) {
  if (!r.ran) return fmt::format("{}: DID NOT RUN: {}", r.intersection, r.error);
  return fmt::format(
      "{}: {} junction collision{} ({} between conflicting groups; {} other), {} vehicles, {} "
      "conflict monitor violations, CPU {:.1f} s",
      r.intersection, r.junction_collisions, r.junction_collisions == 1 ? "" : "s",
      r.intergreen_collisions, r.other_collisions, r.vehicles_departed, r.monitor_violations,
      r.cpu_s);
}

}  // namespace

std::vector<std::string> CollisionCommand(const CollisionBatchOptions& o,
                                          const std::string& intersection, const fs::path& dir) {
  const CollisionOracleOptions& c = o.oracle;
  std::vector<std::string> argv = {o.program.string(),
                                   "collisions",
                                   o.city.string(),
                                   "--intersection",
                                   intersection,
                                   "--duration",
                                   SumoSeconds(c.duration),
                                   "--time-of-day",
                                   internal::HoursMinutes(c.time_of_day),
                                   "--headway",
                                   SumoSeconds(c.headway),
                                   "--seed",
                                   std::to_string(c.seed)};
  if (c.intergreens.kind == IntergreenChange::Kind::kScale) {
    argv.insert(argv.end(), {"--scale-intergreens", fmt::format("{:g}", c.intergreens.factor)});
  } else if (c.intergreens.kind == IntergreenChange::Kind::kMatrix) {
    argv.emplace_back("--intergreens-at-matrix");
  }
  argv.insert(argv.end(), {"--out", dir.string()});
  return argv;
}

CollisionBatchResult RunCollisionBatch(const CollisionBatchOptions& o) {
  AUTODRIVE_THROW_UNLESS(!o.intersections.empty(), "no signalised intersection to run");
  AUTODRIVE_THROW_UNLESS(!o.program.empty(), "no program to run each intersection with");
  AUTODRIVE_THROW_UNLESS(!o.oracle.out_dir.empty(), "no output folder");
  AUTODRIVE_THROW_UNLESS(o.oracle.time_of_day % std::chrono::minutes(1) == Duration{0},
                         "the time of day must be whole minutes");
  fs::create_directories(o.oracle.out_dir);
  const fs::path out = fs::absolute(o.oracle.out_dir);

  CollisionBatchResult result;
  for (const std::string& x : o.intersections) {
    if (o.progress)
      o.progress(fmt::format("{}: running ({} s simulated)", x, SumoSeconds(o.oracle.duration)));
    IntersectionRun r = Run(o, x, out);
    if (o.progress) o.progress(RunLine(r));
    result.junction_collisions += r.junction_collisions;
    if (!r.ran) ++result.failed;
    result.runs.push_back(std::move(r));
  }

  std::string t = fmt::format(
      "Intergreen collision oracle: {} ({} s from {}, {}): {} junction "
      "collision{} in all{}\n",
      o.city.string(), SumoSeconds(o.oracle.duration), internal::HoursMinutes(o.oracle.time_of_day),
      o.oracle.intergreens.Describe(), result.junction_collisions,
      result.junction_collisions == 1 ? "" : "s",
      result.failed > 0 ? fmt::format(", {} run(s) did not run", result.failed) : "");
  nlohmann::json runs = nlohmann::json::array();
  for (const IntersectionRun& r : result.runs) {
    t += RunLine(r) + "\n  replay: " + Quoted(CollisionCommand(o, r.intersection, r.dir)) +
         "\n  report: " + (r.dir / "report.txt").string() + "\n";
    runs.push_back({{"intersection", r.intersection},
                    {"ran", r.ran},
                    {"exit_code", r.exit_code},
                    {"error", r.error},
                    {"junction_collisions", r.junction_collisions},
                    {"intergreen_collisions", r.intergreen_collisions},
                    {"other_collisions", r.other_collisions},
                    {"vehicles_departed", r.vehicles_departed},
                    {"monitor_violations", r.monitor_violations},
                    {"cpu_s", r.cpu_s},
                    {"wall_s", r.wall_s},
                    {"dir", r.dir.string()},
                    {"replay", Quoted(CollisionCommand(o, r.intersection, r.dir))}});
  }
  result.text = t;
  const nlohmann::json j = {{"city", o.city.string()},
                            {"duration_s", ToSeconds(o.oracle.duration)},
                            {"time_of_day_s", ToSeconds(o.oracle.time_of_day)},
                            {"intergreens_changed", o.oracle.intergreens.Describe()},
                            {"headway_s", ToSeconds(o.oracle.headway)},
                            {"seed", o.oracle.seed},
                            {"junction_collisions", result.junction_collisions},
                            {"failed", result.failed},
                            {"runs", runs}};
  result.text_summary = out / "summary.txt";
  result.json_summary = out / "summary.json";
  WriteFile(result.text_summary, result.text);
  WriteFile(result.json_summary, j.dump(2) + "\n");
  return result;
}

}  // namespace autodrive::traffic::nema
