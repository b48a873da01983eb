#include "traffic/nema/random_batch.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "traffic/nema/internal/child_run.h"
#include "traffic/nema/internal/io.h"
#include "traffic/nema/nema_program.h"

#include "common/error.h"
#include "common/process.h"

namespace autodrive::traffic::nema {

namespace {

namespace fs = std::filesystem;
using internal::Quoted;
using internal::ReadFile;
using internal::WriteFile;

// The seed's report.json into `o`.
void ReadReport(const fs::path& file, SeedOutcome& o) {
  const nlohmann::json j = nlohmann::json::parse(ReadFile(file));
  o.matched = j.at("match").get<bool>();
  const nlohmann::json& q = j.at("sequence");
  o.intervals = q.at("compared").get<std::size_t>();
  o.max_difference_s = q.at("max_difference_s").get<double>();
  for (const nlohmann::json& e : q.at("episodes")) {
    SeedDifference d;
    d.text = e.at("text").get<std::string>();
    if (e.contains("diagnosis")) {
      const nlohmann::json& n = e.at("diagnosis");
      d.rule = n.at("rule").get<std::string>();
      d.summary = n.at("summary").get<std::string>();
      d.evidence = n.at("evidence").get<std::string>();
      d.remedy = n.at("remedy").get<std::string>();
    }
    o.differences.push_back(std::move(d));
  }
}

std::size_t CountCalls(const fs::path& file) {
  std::ifstream in(file);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != '#') ++n;
  }
  return n;
}

std::string Seconds(Duration d) { return SumoSeconds(d); }

}  // namespace

std::vector<std::string> SeedCommand(const RandomBatchOptions& o, std::uint64_t seed,
                                     const fs::path& dir) {
  return {o.program.string(),
          "crosscheck",
          o.city.string(),
          o.intersection,
          o.plan,
          "--random-calls",
          std::to_string(seed),
          "--mean-gap",
          Seconds(o.mean_gap),
          "--calls-from",
          Seconds(o.calls_from),
          "--duration",
          Seconds(o.duration),
          "--tolerance",
          Seconds(o.tolerance),
          "--compare",
          "sequence",
          "--out",
          dir.string()};
}

namespace {

// The summary for people.
std::string SummaryText(const RandomBatchOptions& o, const RandomBatchResult& r) {
  std::string t;
  const auto line = [&](const std::string& x) { t += x + "\n"; };
  line(fmt::format(
      "Random call crosscheck of {} plan {} ({}): the SCM's controller against SUMO's NEMA "
      "controller",
      o.intersection, o.plan, o.city.string()));
  line(fmt::format(
      "{} seeds from {}, {} s each, mean gap {} s, calls from {} s, sequence comparison (phase "
      "order, every start and end within {} s)",
      o.seeds, o.first_seed, Seconds(o.duration), Seconds(o.mean_gap), Seconds(o.calls_from),
      Seconds(o.tolerance)));
  line(fmt::format("verdict: {}: {} of {} seeds matched (required {}){}",
                   r.passed ? "PASS" : "FAIL", r.matched, o.seeds, o.required,
                   r.failed > 0 ? fmt::format(", {} did not run", r.failed) : ""));
  double wall = 0;
  for (const SeedOutcome& s : r.seeds) wall += s.wall_s;
  line(fmt::format("wall time {:.1f} s in all ({:.2f} s a seed)", wall, wall / o.seeds));
  if (!r.rules.empty()) {
    line("");
    line("rules behind the differences (seeds where it is the first / stretches in all):");
    for (const auto& [rule, counts] : r.rules) {
      line(fmt::format("  {:<26} {:>3} / {:>3}", rule, counts.first, counts.second));
    }
  }
  for (const SeedOutcome& s : r.seeds) {
    line("");
    if (!s.ran) {
      line(fmt::format("seed {}: DID NOT RUN: {}", s.seed, s.error));
      continue;
    }
    line(fmt::format(
        "seed {}: {} ({} calls, {} intervals in sequence, max difference {:.1f} s{})", s.seed,
        s.matched ? "MATCH" : "DIFFERENT", s.calls, s.intervals, s.max_difference_s,
        s.differences.empty() ? ""
                              : fmt::format(", {} stretch{} of differences", s.differences.size(),
                                            s.differences.size() == 1 ? "" : "es")));
    if (s.differences.empty()) continue;
    const SeedDifference& f = s.differences.front();
    line("  first difference: " + f.text);
    line(fmt::format("  rule: {}: {}", f.rule, f.summary));
    line("  evidence: " + f.evidence);
    line("  removed by: " + f.remedy);
    for (std::size_t i = 1; i < s.differences.size(); ++i) {
      line(fmt::format("  then {}: {}", s.differences[i].rule, s.differences[i].text));
    }
    line("  replay: " + Quoted(SeedCommand(o, s.seed, s.dir)));
    line("  files: " + s.dir.string());
  }
  return t;
}

// The summary as JSON.
nlohmann::json SummaryJson(const RandomBatchOptions& o, const RandomBatchResult& r) {
  nlohmann::json j = {{"city", o.city.string()},
                      {"intersection", o.intersection},
                      {"plan", o.plan},
                      {"seeds", o.seeds},
                      {"first_seed", o.first_seed},
                      {"duration_s", ToSeconds(o.duration)},
                      {"tolerance_s", ToSeconds(o.tolerance)},
                      {"mean_gap_s", ToSeconds(o.mean_gap)},
                      {"calls_from_s", ToSeconds(o.calls_from)},
                      {"required", o.required},
                      {"matched", r.matched},
                      {"failed", r.failed},
                      {"passed", r.passed}};
  nlohmann::json rules = nlohmann::json::object();
  for (const auto& [rule, counts] : r.rules) {
    rules[rule] = {{"first_difference_of_seeds", counts.first}, {"stretches", counts.second}};
  }
  j["rules"] = rules;
  nlohmann::json seeds = nlohmann::json::array();
  for (const SeedOutcome& s : r.seeds) {
    nlohmann::json d = nlohmann::json::array();
    for (const SeedDifference& x : s.differences) {
      d.push_back({{"text", x.text},
                   {"rule", x.rule},
                   {"summary", x.summary},
                   {"evidence", x.evidence},
                   {"remedy", x.remedy}});
    }
    seeds.push_back({{"seed", s.seed},
                     {"ran", s.ran},
                     {"match", s.matched},
                     {"exit_code", s.exit_code},
                     {"error", s.error},
                     {"calls", s.calls},
                     {"intervals", s.intervals},
                     {"max_difference_s", s.max_difference_s},
                     {"first_difference", d.empty() ? nlohmann::json(nullptr) : d.front()},
                     {"differences", d},
                     {"wall_s", s.wall_s},
                     {"dir", s.dir.string()},
                     {"replay", Quoted(SeedCommand(o, s.seed, s.dir))}});
  }
  j["seed_results"] = seeds;
  return j;
}

}  // namespace

RandomBatchResult RunRandomBatch(const RandomBatchOptions& o) {
  AUTODRIVE_THROW_UNLESS(o.seeds >= 1, "--seeds must be at least 1, got " << o.seeds);
  AUTODRIVE_THROW_UNLESS(o.required >= 0 && o.required <= o.seeds,
                         "--require must be in [0, --seeds " << o.seeds << "], got " << o.required);
  AUTODRIVE_THROW_UNLESS(!o.program.empty(), "no program to run each seed with");
  AUTODRIVE_THROW_UNLESS(!o.out_dir.empty(), "no output folder");
  fs::create_directories(o.out_dir);
  const fs::path out = fs::absolute(o.out_dir);

  RandomBatchResult r;
  for (int k = 0; k < o.seeds; ++k) {
    SeedOutcome s;
    s.seed = o.first_seed + static_cast<std::uint64_t>(k);
    s.dir = out / fmt::format("seed-{}", s.seed);
    const internal::ChildRun run =
        internal::RunChild(SeedCommand(o, s.seed, s.dir), s.dir, o.seed_timeout,
                           [&](const fs::path& report) { ReadReport(report, s); });
    s.exit_code = run.exit_code;
    s.ran = run.ran;
    s.error = run.error;
    s.wall_s = run.wall_s;
    s.calls = CountCalls(s.dir / "calls.txt");
    if (!s.ran) ++r.failed;
    if (s.ran && s.matched) ++r.matched;
    for (std::size_t i = 0; i < s.differences.size(); ++i) {
      const std::string rule = s.differences[i].rule.empty() ? "?" : s.differences[i].rule;
      auto& [first, all] = r.rules[rule];
      if (i == 0) ++first;
      ++all;
    }
    r.seeds.push_back(std::move(s));
  }
  r.passed = r.failed == 0 && r.matched >= o.required;

  r.text = SummaryText(o, r);
  const nlohmann::json j = SummaryJson(o, r);
  r.text_summary = out / "summary.txt";
  r.json_summary = out / "summary.json";
  WriteFile(r.text_summary, r.text);
  WriteFile(r.json_summary, j.dump(2) + "\n");
  return r;
}

}  // namespace autodrive::traffic::nema
