// autodrive-scm-nema: a city plan as a program of SUMO's NEMA controller, and the crosscheck of
// the SCM's controller against it (docs/controller-crosscheck.md).
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "traffic/nema/atspm_check.h"
#include "traffic/nema/call_script.h"
#include "traffic/nema/collision_batch.h"
#include "traffic/nema/collision_oracle.h"
#include "traffic/nema/crosscheck.h"
#include "traffic/nema/nema_program.h"
#include "traffic/nema/random_batch.h"
#include "traffic/sumo_api.h"

#include "common/error.h"
#include "common/logging.h"
#include "common/time.h"
#include "scm/core/city.h"

namespace {

using namespace autodrive;
using namespace autodrive::traffic::nema;

// Exit codes.
constexpr int kMatch = 0;
constexpr int kDifferent = 1;
constexpr int kBadInput = 2;
constexpr int kSumoFailed = 3;

// "PHASE=SECONDS" of --test-sumo-max-green.
std::map<std::uint32_t, Duration> MaxGreens(const std::vector<std::string>& given) {
  std::map<std::uint32_t, Duration> out;
  for (const std::string& g : given) {
    const std::size_t eq = g.find('=');
    std::size_t used_phase = 0;
    std::size_t used_seconds = 0;
    unsigned long phase = 0;
    double seconds = 0;
    try {
      if (eq != std::string::npos) {
        phase = std::stoul(g.substr(0, eq), &used_phase);
        seconds = std::stod(g.substr(eq + 1), &used_seconds);
      }
    } catch (const std::exception&) {
      used_phase = 0;
    }
    AUTODRIVE_THROW_UNLESS(eq != std::string::npos && used_phase == eq && used_phase > 0 &&
                               used_seconds == g.size() - eq - 1 && seconds > 0,
                           "--test-sumo-max-green wants PHASE=SECONDS, got \"" << g << "\"");
    out[static_cast<std::uint32_t>(phase)] = FromSeconds(seconds);
  }
  return out;
}

// "HH:MM" of --time-of-day, as a time since midnight.
Duration TimeOfDay(const std::string& text) {
  int hours = -1;
  int minutes = -1;
  char colon = 0;
  std::size_t used = 0;
  try {
    hours = std::stoi(text, &used);
    if (used < text.size()) colon = text[used];
    std::size_t more = 0;
    if (colon == ':') minutes = std::stoi(text.substr(used + 1), &more);
    used += 1 + more;
  } catch (const std::exception&) {
    hours = -1;
  }
  AUTODRIVE_THROW_UNLESS(colon == ':' && used == text.size() && hours >= 0 && hours < 24 &&
                             minutes >= 0 && minutes < 60,
                         "--time-of-day wants HH:MM (00:00 to 23:59), got \"" << text << "\"");
  return std::chrono::hours(hours) + std::chrono::minutes(minutes);
}

// The city file, and the intersection and plan of the subcommands that take them.
struct Positional {
  std::string city, intersection, plan;

  void AddCity(CLI::App* sub) {
    sub->add_option("CITY", city, "city file (config/cities/*.yaml)")
        ->required()
        ->check(CLI::ExistingFile);
  }
  void AddAll(CLI::App* sub) {
    AddCity(sub);
    sub->add_option("INTERSECTION", intersection, "signalised intersection: name or id")
        ->required();
    sub->add_option("PLAN", plan, "the plan's name (fixed time or actuated)")->required();
  }
};

// `export CITY INTERSECTION PLAN [-o FILE] [--check DIR]`.
struct ExportCommand {
  CLI::App* sub = nullptr;
  std::string out, check;

  void Add(CLI::App& app, Positional& p) {
    sub = app.add_subcommand(
        "export",
        "write a SUMO additional file with the plan as one tlLogic of type NEMA (programID "
        "NEMA) for the intersection's junction in the network the co-simulation exports");
    p.AddAll(sub);
    sub->add_option("-o,--output", out, "the file to write (default: standard output)");
    sub->add_option("--check", check,
                    "also export the city's SUMO network into this folder and run sumo on it "
                    "with the file for 1 s: fails when SUMO refuses it");
  }

  int Run(const scm::City& city, const Positional& p) const {
    const NemaProgram program = NemaProgramOf(city, FindPlan(city, p.intersection, p.plan));
    const std::string xml = NemaAdditionalXml(program);
    if (out.empty()) {
      std::fputs(xml.c_str(), stdout);
      AUTODRIVE_THROW_UNLESS(check.empty(), "--check needs -o FILE");
      return kMatch;
    }
    {
      std::FILE* file = std::fopen(out.c_str(), "wb");
      AUTODRIVE_THROW_UNLESS(file != nullptr, "cannot write " << out);
      const bool ok = std::fputs(xml.c_str(), file) >= 0;
      AUTODRIVE_THROW_UNLESS(std::fclose(file) == 0 && ok, "cannot write " << out);
    }
    std::string ring;
    for (std::uint32_t n : program.rings[0]) ring += (ring.empty() ? "" : ",") + std::to_string(n);
    std::fprintf(stderr, "wrote %s: tlLogic %s program %s, ring %s, cycle %s s\n", out.c_str(),
                 program.tls.c_str(), program.program_id.c_str(), ring.c_str(),
                 SumoSeconds(program.cycle).c_str());
    if (!check.empty()) {
      CheckWithSumo(city, out, check);
      std::fprintf(stderr, "SUMO accepts it (network in %s)\n", check.c_str());
    }
    return kMatch;
  }
};

// `crosscheck CITY INTERSECTION PLAN (--cycles N | --duration S) --out DIR ...`.
struct CrosscheckCommand {
  CLI::App* sub = nullptr;
  int cycles = 0;
  double duration_s = 0.0;
  std::string calls_path, out_dir;
  std::uint64_t random_seed = 0;
  double mean_gap_s = 20.0;
  double calls_from_s = 0.0;
  std::string compare = "pairs";
  double tolerance_s = 0.1;
  double our_start_s = 0.0;
  std::vector<std::string> test_max_green;
  CLI::Option* cycles_opt = nullptr;
  CLI::Option* duration_opt = nullptr;
  CLI::Option* random_opt = nullptr;
  CLI::Option* our_start_opt = nullptr;

  void Add(CLI::App& app, Positional& p) {
    sub = app.add_subcommand(
        "crosscheck",
        "run the plan in SUMO's NEMA controller (libsumo, no vehicles, 0.1 s steps) and in the "
        "SCM's controller in lockstep, with the same detector calls, and compare every green, "
        "yellow and red clearance of each phase; writes DIR/report.txt and DIR/report.json");
    p.AddAll(sub);
    cycles_opt =
        sub->add_option("--cycles", cycles, "cycles to compare, after the controller's start-up")
            ->check(CLI::Range(1, 1000));
    duration_opt =
        sub->add_option("--duration", duration_s,
                        "instead of --cycles: compare up to this time on SUMO's clock (s); the "
                        "run goes on for one more cycle so that the last intervals end")
            ->check(CLI::Range(1.0, 86400.0));
    cycles_opt->excludes(duration_opt);
    CLI::Option* calls_opt =
        sub->add_option("--calls", calls_path,
                        "call script: lines \"phase on_s [off_s]\" (SUMO's clock; # comments)")
            ->check(CLI::ExistingFile);
    random_opt = sub->add_option(
        "--random-calls", random_seed,
        "instead of --calls: draw each phase's detector calls from this seed "
        "(docs/controller-crosscheck.md), written to DIR/calls.txt; ours then starts so that "
        "its first green is at SUMO's time 0 unless --our-start says otherwise");
    random_opt->excludes(calls_opt);
    sub->add_option("--mean-gap", mean_gap_s,
                    "random calls: mean gap between a phase's vehicles (s), from one leaving "
                    "its detector to the next arriving")
        ->check(CLI::Range(0.1, 3600.0))
        ->capture_default_str()
        ->needs(random_opt);
    sub->add_option("--calls-from", calls_from_s,
                    "random calls: no vehicle before this time (s; 0: from the start, the "
                    "default). SUMO's first green times nothing before its min green ends "
                    "(docs/controller-crosscheck.md, rule first_green): calls from its end "
                    "leave that start-up out")
        ->check(CLI::Range(0.0, 86400.0))
        ->capture_default_str()
        ->needs(random_opt);
    sub->add_option("--compare", compare,
                    "which comparison gives the verdict (both are reported): pairs (each "
                    "interval with SUMO's nearest of its phase and kind, cycle lengths equal) or "
                    "sequence (the same phases in the same order, every start and end within "
                    "the tolerance: for actuated runs)")
        ->check(CLI::IsMember({"pairs", "sequence"}))
        ->capture_default_str();
    sub->add_option("--out", out_dir, "output folder (created)")->required();
    sub->add_option("--tolerance", tolerance_s,
                    "largest difference of an interval's start or end that still matches (s)")
        ->check(CLI::Range(0.0, 60.0))
        ->capture_default_str();
    our_start_opt = sub->add_option("--our-start", our_start_s,
                                    "when the SCM's controller starts, on SUMO's clock (s); "
                                    "negative: it runs its start-up alone before SUMO's time 0");
    our_start_opt->check(CLI::Range(-86400.0, 86400.0))->capture_default_str();
    // Test only (hidden): SUMO runs phase PHASE with this max green, to show a difference.
    sub->add_option("--test-sumo-max-green", test_max_green, "")->group("");
  }

  int Run(const scm::City& city, const Positional& p) const {
    AUTODRIVE_THROW_UNLESS(cycles_opt->count() > 0 || duration_opt->count() > 0,
                           "give --cycles N (cycles to compare) or --duration S");
    CrosscheckOptions o;
    o.intersection = p.intersection;
    o.plan = p.plan;
    o.cycles = cycles;
    if (duration_opt->count() > 0) o.duration = FromSeconds(duration_s);
    if (!calls_path.empty()) o.calls = LoadCallScript(calls_path);
    o.out_dir = out_dir;
    o.tolerance = FromSeconds(tolerance_s);
    o.our_start = FromSeconds(our_start_s);
    o.compare = compare == "sequence" ? ComparisonMode::kSequence : ComparisonMode::kPairs;
    if (random_opt->count() > 0) {
      o.random_calls = RandomCalls{random_seed, {}};
      o.random_calls->params.mean_gap = FromSeconds(mean_gap_s);
      o.random_calls->params.calls_from = FromSeconds(calls_from_s);
      if (our_start_opt->count() == 0) {
        const scm::IntersectionModel& x = *FindPlan(city, p.intersection, p.plan).model;
        o.our_start = -(x.startup_flash + x.startup_all_red);
      }
    }
    o.sumo_max_green = MaxGreens(test_max_green);
    const CrosscheckResult result = RunCrosscheck(city, o);
    std::fputs(result.text.c_str(), stdout);
    return result.passed ? kMatch : kDifferent;
  }
};

// `crosscheck-random CITY INTERSECTION PLAN --out DIR ...`.
struct RandomCommand {
  CLI::App* sub = nullptr;
  RandomBatchOptions batch;
  double duration_s = 900.0;
  double tolerance_s = 0.2;
  double mean_gap_s = 20.0;
  double calls_from_s = 0.0;
  int required = -1;
  std::string out;

  void Add(CLI::App& app, Positional& p) {
    sub = app.add_subcommand(
        "crosscheck-random",
        "run the crosscheck with seeded random calls for --seeds seeds (each a child process: "
        "crosscheck --random-calls SEED --compare sequence) and write DIR/summary.txt and "
        "DIR/summary.json: how many matched and, for each that did not, its differences with "
        "the rule behind each and the setting that removes it. Exit 0 when at least --require "
        "seeds matched");
    p.AddAll(sub);
    sub->add_option("--seeds", batch.seeds, "how many seeds")
        ->check(CLI::Range(1, 10000))
        ->capture_default_str();
    sub->add_option("--first-seed", batch.first_seed, "the first seed")->capture_default_str();
    sub->add_option("--duration", duration_s, "seconds of each run (SUMO's clock)")
        ->check(CLI::Range(1.0, 86400.0))
        ->capture_default_str();
    sub->add_option("--tolerance", tolerance_s,
                    "largest difference of an interval's start or end that still matches (s)")
        ->check(CLI::Range(0.0, 60.0))
        ->capture_default_str();
    sub->add_option("--mean-gap", mean_gap_s,
                    "mean gap between a phase's vehicles (s), as crosscheck --mean-gap")
        ->check(CLI::Range(0.1, 3600.0))
        ->capture_default_str();
    sub->add_option("--calls-from", calls_from_s,
                    "no vehicle before this time (s), as crosscheck --calls-from")
        ->check(CLI::Range(0.0, 86400.0))
        ->capture_default_str();
    sub->add_option("--require", required, "seeds that must match for exit code 0 (default: all)");
    sub->add_option("--out", out, "output folder (created): DIR/seed-N/ per seed")->required();
  }

  int Run(const scm::City& city, const Positional& p) {
    (void)FindPlan(city, p.intersection, p.plan);  // names a bad intersection or plan at once
    batch.program = std::filesystem::read_symlink("/proc/self/exe");
    batch.city = std::filesystem::absolute(p.city);
    batch.intersection = p.intersection;
    batch.plan = p.plan;
    batch.duration = FromSeconds(duration_s);
    batch.tolerance = FromSeconds(tolerance_s);
    batch.mean_gap = FromSeconds(mean_gap_s);
    batch.calls_from = FromSeconds(calls_from_s);
    batch.required = required < 0 ? batch.seeds : required;
    batch.out_dir = out;
    const RandomBatchResult result = RunRandomBatch(batch);
    std::fputs(result.text.c_str(), stdout);
    if (result.failed > 0) return kSumoFailed;
    return result.passed ? kMatch : kDifferent;
  }
};

// `collisions CITY [--intersection X] [--duration S] [--halve-intergreens] --out DIR ...`.
struct CollisionsCommand {
  CLI::App* sub = nullptr;
  CollisionOracleOptions oracle;
  double duration_s = 3600.0;
  double headway_s = 6.0;
  std::string time_of_day = "12:00";
  std::string intersection;
  std::string out;
  bool halve = false;
  double scale = 1.0;
  bool at_matrix = false;
  CLI::Option* scale_opt = nullptr;

  void Add(CLI::App& app, Positional& p) {
    sub = app.add_subcommand(
        "collisions",
        "the intergreen collision oracle: the SCM's controllers (each intersection's scheduled "
        "fixed-time plan) drive SUMO's lights through the lamps as the co-simulation does, on "
        "the city's network (x14, 0.1 s steps, junction collision checks), with slow clearing "
        "and fast entering vehicles that trust the signal through every conflicting movement; "
        "writes DIR/report.txt and DIR/report.json with every collision SUMO reported. Exit 0 "
        "when SUMO reported no junction collision, 1 when it did. See "
        "docs/controller-crosscheck.md, \"Intergreen oracle\"");
    p.AddCity(sub);
    sub->add_option("--intersection", intersection,
                    "traffic through this signalised intersection only (name or id; every "
                    "intersection's controller runs); default: each signalised intersection in "
                    "a run of its own (DIR/<intersection>/, DIR/summary.txt and "
                    "DIR/summary.json)");
    sub->add_option("--duration", duration_s, "simulated seconds")
        ->check(CLI::Range(1.0, 86400.0))
        ->capture_default_str();
    CLI::Option* halve_opt =
        sub->add_flag("--halve-intergreens", halve,
                      "the negative control: every group's yellow + red clearance (the yellow "
                      "kept, the red cut) and every intergreen matrix entry halved in memory "
                      "after loading");
    scale_opt = sub->add_option("--scale-intergreens", scale,
                                "as --halve-intergreens with another factor (0 < F <= 1): "
                                "where collisions begin")
                    ->check(CLI::Range(0.01, 1.0));
    CLI::Option* matrix_opt =
        sub->add_flag("--intergreens-at-matrix", at_matrix,
                      "every group's yellow + red clearance at the largest entry of its row of "
                      "the intergreen matrix (the yellow kept), in memory after loading");
    halve_opt->excludes(scale_opt)->excludes(matrix_opt);
    scale_opt->excludes(matrix_opt);
    sub->add_option("--time-of-day", time_of_day,
                    "local time at the start (HH:MM): chooses the scheduled plans, which must "
                    "be fixed time for the whole run")
        ->capture_default_str();
    sub->add_option("--headway", headway_s,
                    "mean seconds between two vehicles of one ingress lane (random arrivals)")
        ->check(CLI::Range(0.5, 3600.0))
        ->capture_default_str();
    sub->add_option("--seed", oracle.seed, "SUMO's seed")->capture_default_str();
    sub->add_option("--out", out, "output folder (created)")->required();
  }

  int Run(const scm::City& city, const Positional& p) {
    oracle.duration = FromSeconds(duration_s);
    oracle.time_of_day = TimeOfDay(time_of_day);
    oracle.headway = FromSeconds(headway_s);
    if (halve || scale_opt->count() > 0) {
      oracle.intergreens = {IntergreenChange::Kind::kScale, halve ? 0.5 : scale};
    } else if (at_matrix) {
      oracle.intergreens = {IntergreenChange::Kind::kMatrix, 1.0};
    }
    if (!intersection.empty()) oracle.intersection = intersection;
    oracle.out_dir = out;
    const auto progress = [](const std::string& line) {
      std::fprintf(stderr, "autodrive-scm-nema collisions: %s\n", line.c_str());
    };
    (void)CheckCollisionOracleOptions(city, oracle);  // bad input named at once
    if (oracle.intersection) {
      oracle.progress = progress;
      const CollisionOracleResult result = RunCollisionOracle(city, oracle);
      std::fputs(result.text.c_str(), stdout);
      return result.junction_collisions == 0 ? kMatch : kDifferent;
    }
    // Each intersection's traffic in a run of its own (collision_batch.h).
    CollisionBatchOptions batch;
    batch.program = std::filesystem::read_symlink("/proc/self/exe");
    batch.city = std::filesystem::absolute(p.city);
    batch.oracle = oracle;
    for (const scm::IntersectionModel& x : city.intersections) {
      batch.intersections.push_back(x.name);
    }
    batch.progress = progress;
    const CollisionBatchResult result = RunCollisionBatch(batch);
    std::fputs(result.text.c_str(), stdout);
    if (result.failed > 0) return kSumoFailed;
    return result.junction_collisions == 0 ? kMatch : kDifferent;
  }
};

// `atspm-check CITY INTERSECTION [--duration S] [--seed N] --out DIR ...`.
struct AtspmCheckCommand {
  CLI::App* sub = nullptr;
  AtspmCheckOptions options;
  double duration_s = 3600.0;
  double headway_s = 40.0;
  double shift_s = 0.0;
  std::string time_of_day = "12:00";
  std::string out;

  void Add(CLI::App& app, Positional& p) {
    sub = app.add_subcommand(
        "atspm-check",
        "ATSPM measures against SUMO's own records: the oracle's co-simulation (the SCM's "
        "controllers driving SUMO's lights, 0.1 s lockstep) with random arrivals through one "
        "intersection, a detection point per ingress lane seen by both the SCM (a zone: 82/81 "
        "in its hires log) and SUMO (an instantInductionLoop), SUMO's SaveTLSSwitchTimes and "
        "SaveTLSStates; compares scm/atspm's arrivals on green per phase and 15 min with the "
        "loop entries inside SUMO's greens, and the split monitor with SUMO's green + yellow + "
        "red. Writes DIR/report.txt and DIR/report.json; exit 0 when every difference is "
        "within tolerance, 1 otherwise. See docs/atspm.md, \"Checked against SUMO\"");
    p.AddCity(sub);
    sub->add_option("INTERSECTION", options.intersection, "signalised intersection: name or id")
        ->required();
    sub->add_option("--duration", duration_s, "simulated seconds")
        ->check(CLI::Range(1.0, 86400.0))
        ->capture_default_str();
    sub->add_option("--seed", options.seed, "SUMO's seed")->capture_default_str();
    sub->add_option("--headway", headway_s,
                    "mean seconds between two vehicles of one ingress lane (random arrivals)")
        ->check(CLI::Range(0.5, 3600.0))
        ->capture_default_str();
    sub->add_option("--time-of-day", time_of_day,
                    "local time at the start (HH:MM): the scheduled plan, fixed time for the "
                    "whole run")
        ->capture_default_str();
    sub->add_option("--setback", options.setback_m,
                    "the detection point, lab metres upstream of the stop line")
        ->check(CLI::Range(0.02, 10.0))
        ->capture_default_str();
    sub->add_option("--test-shift-sumo-windows", shift_s,
                    "a test's perturbation: SUMO's greens of the lowest-numbered phase moved by "
                    "S seconds when read (the check must fail)");
    sub->add_flag("--literal", options.literal_verdict,
                  "the verdict on SUMO's loop stamps inside its greens as they are, not on the "
                  "entries at the times the SCM's detector reads them (the step after SUMO's "
                  "step that moved the vehicle past the loop)");
    sub->add_option("--out", out, "output folder (created)")->required();
  }

  int Run(const scm::City& city) {
    options.duration = FromSeconds(duration_s);
    options.headway = FromSeconds(headway_s);
    options.time_of_day = TimeOfDay(time_of_day);
    options.test_shift_sumo_windows = FromSeconds(shift_s);
    options.out_dir = out;
    options.progress = [](const std::string& line) {
      std::fprintf(stderr, "autodrive-scm-nema atspm-check: %s\n", line.c_str());
    };
    const AtspmCheckResult result = RunAtspmCheck(city, options);
    std::fputs(result.text.c_str(), stdout);
    return result.passed ? kMatch : kDifferent;
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-scm-nema: a city's signal plan as a program of SUMO's NEMA controller "
      "(tlLogic type=\"NEMA\"), the crosscheck of the SCM's intersection controller against "
      "SUMO running that program, and the intergreen collision oracle. See "
      "docs/controller-crosscheck.md.\n"
      "Exit codes: 0 written / matched (collisions: no junction collision), 1 the crosscheck "
      "found a difference (crosscheck-random: fewer seeds matched than required; collisions: "
      "SUMO reported junction collisions), 2 bad input (including a plan SUMO's NEMA "
      "controller cannot run), 3 SUMO failed (crosscheck-random, collisions: a run did not "
      "run)."};
  app.require_subcommand(1);
  Positional positional;
  ExportCommand exp;
  CrosscheckCommand cross;
  RandomCommand random;
  CollisionsCommand collisions;
  AtspmCheckCommand atspm;
  exp.Add(app, positional);
  cross.Add(app, positional);
  random.Add(app, positional);
  collisions.Add(app, positional);
  atspm.Add(app, positional);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kMatch : kBadInput;
  }
  // Library logs (the co-simulation's collisions and teleports) on stderr: stdout is the report.
  InitLogging("autodrive-scm-nema", spdlog::level::warn);
  try {
    const scm::City city = scm::LoadCity(positional.city);
    if (collisions.sub->parsed()) return collisions.Run(city, positional);
    if (atspm.sub->parsed()) return atspm.Run(city);
    if (random.sub->parsed()) return random.Run(city, positional);
    if (exp.sub->parsed()) return exp.Run(city, positional);
    return cross.Run(city, positional);
  } catch (const InputError& e) {
    std::fprintf(stderr, "autodrive-scm-nema: %s\n", e.what());
    return kBadInput;
  } catch (const std::filesystem::filesystem_error& e) {
    std::fprintf(stderr, "autodrive-scm-nema: %s\n", e.what());
    return kBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-scm-nema: %s\n", e.what());
    return kSumoFailed;
  }
}
