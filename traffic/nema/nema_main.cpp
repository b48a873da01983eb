// autodrive-scm-nema: a city plan as a program of SUMO's NEMA controller, and the crosscheck of
// the SCM's controller against it (docs/controller-crosscheck.md).
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "traffic/nema/call_script.h"
#include "traffic/nema/crosscheck.h"
#include "traffic/nema/nema_program.h"
#include "traffic/nema/random_batch.h"
#include "traffic/sumo_api.h"

#include "common/error.h"
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-scm-nema: a city's signal plan as a program of SUMO's NEMA controller "
      "(tlLogic type=\"NEMA\"), and the crosscheck of the SCM's intersection controller "
      "against SUMO running that program. See docs/controller-crosscheck.md.\n"
      "Exit codes: 0 written / matched, 1 the crosscheck found a difference (crosscheck-random: "
      "fewer seeds matched than required), 2 bad input (including a plan SUMO's NEMA controller "
      "cannot run), 3 SUMO failed (crosscheck-random: a seed did not run)."};
  app.require_subcommand(1);

  std::string city_path, intersection, plan;
  const auto positional = [&](CLI::App* sub) {
    sub->add_option("CITY", city_path, "city file (config/cities/*.yaml)")
        ->required()
        ->check(CLI::ExistingFile);
    sub->add_option("INTERSECTION", intersection, "signalised intersection: name or id")
        ->required();
    sub->add_option("PLAN", plan, "the plan's name (fixed time or actuated)")->required();
  };

  std::string export_out;
  std::string export_check;
  CLI::App* exp = app.add_subcommand(
      "export",
      "write a SUMO additional file with the plan as one tlLogic of type NEMA (programID NEMA) "
      "for the intersection's junction in the network the co-simulation exports");
  positional(exp);
  exp->add_option("-o,--output", export_out, "the file to write (default: standard output)");
  exp->add_option("--check", export_check,
                  "also export the city's SUMO network into this folder and run sumo on it with "
                  "the file for 1 s: fails when SUMO refuses it");

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
  CLI::App* cross = app.add_subcommand(
      "crosscheck",
      "run the plan in SUMO's NEMA controller (libsumo, no vehicles, 0.1 s steps) and in the "
      "SCM's controller in lockstep, with the same detector calls, and compare every green, "
      "yellow and red clearance of each phase; writes DIR/report.txt and DIR/report.json");
  positional(cross);
  CLI::Option* cycles_opt =
      cross->add_option("--cycles", cycles, "cycles to compare, after the controller's start-up")
          ->check(CLI::Range(1, 1000));
  CLI::Option* duration_opt =
      cross
          ->add_option("--duration", duration_s,
                       "instead of --cycles: compare up to this time on SUMO's clock (s); the run "
                       "goes on for one more cycle so that the last intervals end")
          ->check(CLI::Range(1.0, 86400.0));
  cycles_opt->excludes(duration_opt);
  CLI::Option* calls_opt =
      cross
          ->add_option("--calls", calls_path,
                       "call script: lines \"phase on_s [off_s]\" (SUMO's clock; # comments)")
          ->check(CLI::ExistingFile);
  CLI::Option* random_opt =
      cross->add_option("--random-calls", random_seed,
                        "instead of --calls: draw each phase's detector calls from this seed "
                        "(docs/controller-crosscheck.md), written to DIR/calls.txt; ours then "
                        "starts so that its first green is at SUMO's time 0 unless --our-start "
                        "says otherwise");
  random_opt->excludes(calls_opt);
  cross
      ->add_option("--mean-gap", mean_gap_s,
                   "random calls: mean gap between a phase's vehicles (s), from one leaving "
                   "its detector to the next arriving")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str()
      ->needs(random_opt);
  cross
      ->add_option("--calls-from", calls_from_s,
                   "random calls: no vehicle before this time (s; 0: from the start, the "
                   "default). SUMO's first green times nothing before its min green ends "
                   "(docs/controller-crosscheck.md, rule first_green): calls from its end leave "
                   "that start-up out")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str()
      ->needs(random_opt);
  cross
      ->add_option("--compare", compare,
                   "which comparison gives the verdict (both are reported): pairs (each interval "
                   "with SUMO's nearest of its phase and kind, cycle lengths equal) or sequence "
                   "(the same phases in the same order, every start and end within the "
                   "tolerance: for actuated runs)")
      ->check(CLI::IsMember({"pairs", "sequence"}))
      ->capture_default_str();
  cross->add_option("--out", out_dir, "output folder (created)")->required();
  cross
      ->add_option("--tolerance", tolerance_s,
                   "largest difference of an interval's start or end that still matches (s)")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
  CLI::Option* our_start_opt =
      cross->add_option("--our-start", our_start_s,
                        "when the SCM's controller starts, on SUMO's clock (s); negative: it runs "
                        "its start-up alone before SUMO's time 0");
  our_start_opt->check(CLI::Range(-86400.0, 86400.0))->capture_default_str();
  // Test only (hidden): SUMO runs phase PHASE with this max green, to show a difference.
  cross->add_option("--test-sumo-max-green", test_max_green, "")->group("");

  RandomBatchOptions batch;
  double batch_duration_s = 900.0;
  double batch_tolerance_s = 0.2;
  double batch_mean_gap_s = 20.0;
  double batch_calls_from_s = 0.0;
  int batch_required = -1;
  std::string batch_out;
  CLI::App* random = app.add_subcommand(
      "crosscheck-random",
      "run the crosscheck with seeded random calls for --seeds seeds (each a child process: "
      "crosscheck --random-calls SEED --compare sequence) and write DIR/summary.txt and "
      "DIR/summary.json: how many matched and, for each that did not, its differences with the "
      "rule behind each and the setting that removes it. Exit 0 when at least --require seeds "
      "matched");
  positional(random);
  random->add_option("--seeds", batch.seeds, "how many seeds")
      ->check(CLI::Range(1, 10000))
      ->capture_default_str();
  random->add_option("--first-seed", batch.first_seed, "the first seed")->capture_default_str();
  random->add_option("--duration", batch_duration_s, "seconds of each run (SUMO's clock)")
      ->check(CLI::Range(1.0, 86400.0))
      ->capture_default_str();
  random
      ->add_option("--tolerance", batch_tolerance_s,
                   "largest difference of an interval's start or end that still matches (s)")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
  random
      ->add_option("--mean-gap", batch_mean_gap_s,
                   "mean gap between a phase's vehicles (s), as crosscheck --mean-gap")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  random
      ->add_option("--calls-from", batch_calls_from_s,
                   "no vehicle before this time (s), as crosscheck --calls-from")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  random->add_option("--require", batch_required,
                     "seeds that must match for exit code 0 (default: all)");
  random->add_option("--out", batch_out, "output folder (created): DIR/seed-N/ per seed")
      ->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kMatch : kBadInput;
  }
  try {
    const scm::City city = scm::LoadCity(city_path);
    if (random->parsed()) {
      (void)FindPlan(city, intersection, plan);  // names a bad intersection or plan at once
      batch.program = std::filesystem::read_symlink("/proc/self/exe");
      batch.city = std::filesystem::absolute(city_path);
      batch.intersection = intersection;
      batch.plan = plan;
      batch.duration = FromSeconds(batch_duration_s);
      batch.tolerance = FromSeconds(batch_tolerance_s);
      batch.mean_gap = FromSeconds(batch_mean_gap_s);
      batch.calls_from = FromSeconds(batch_calls_from_s);
      batch.required = batch_required < 0 ? batch.seeds : batch_required;
      batch.out_dir = batch_out;
      const RandomBatchResult result = RunRandomBatch(batch);
      std::fputs(result.text.c_str(), stdout);
      if (result.failed > 0) return kSumoFailed;
      return result.passed ? kMatch : kDifferent;
    }
    if (exp->parsed()) {
      const NemaProgram program = NemaProgramOf(city, FindPlan(city, intersection, plan));
      const std::string xml = NemaAdditionalXml(program);
      if (export_out.empty()) {
        std::fputs(xml.c_str(), stdout);
        AUTODRIVE_THROW_UNLESS(export_check.empty(), "--check needs -o FILE");
        return kMatch;
      }
      {
        std::FILE* file = std::fopen(export_out.c_str(), "wb");
        AUTODRIVE_THROW_UNLESS(file != nullptr, "cannot write " << export_out);
        const bool ok = std::fputs(xml.c_str(), file) >= 0;
        AUTODRIVE_THROW_UNLESS(std::fclose(file) == 0 && ok, "cannot write " << export_out);
      }
      std::fprintf(
          stderr, "wrote %s: tlLogic %s program %s, ring %s, cycle %s s\n", export_out.c_str(),
          program.tls.c_str(), program.program_id.c_str(),
          [&] {
            std::string r;
            for (std::uint32_t n : program.rings[0]) {
              r += (r.empty() ? "" : ",") + std::to_string(n);
            }
            return r;
          }()
              .c_str(),
          SumoSeconds(program.cycle).c_str());
      if (!export_check.empty()) {
        CheckWithSumo(city, export_out, export_check);
        std::fprintf(stderr, "SUMO accepts it (network in %s)\n", export_check.c_str());
      }
      return kMatch;
    }
    AUTODRIVE_THROW_UNLESS(cycles_opt->count() > 0 || duration_opt->count() > 0,
                           "give --cycles N (cycles to compare) or --duration S");
    CrosscheckOptions o;
    o.intersection = intersection;
    o.plan = plan;
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
        const scm::IntersectionModel& x = *FindPlan(city, intersection, plan).model;
        o.our_start = -(x.startup_flash + x.startup_all_red);
      }
    }
    o.sumo_max_green = MaxGreens(test_max_green);
    const CrosscheckResult result = RunCrosscheck(city, o);
    std::fputs(result.text.c_str(), stdout);
    return result.passed ? kMatch : kDifferent;
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
