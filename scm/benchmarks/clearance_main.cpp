// autodrive-bench-clearance: the twin's clearance measurement for a city (docs/scm.md,
// "Clearances"). For each signalised intersection and each phase plan, the SCM's controller runs
// the plan and gives each end of yellow and each conflicting green; two cars of the lab's size
// then drive every pair of conflicting movements, the first entering on the last instant of
// yellow, the second crossing its stop line as its green starts. Prints, per pair of groups, the
// intergreen, the closest approach of the two footprints and whether they meet. Figures, not
// a test (scm_clearance_test checks the shipped cities).
#include <fmt/format.h>

#include <cstdio>
#include <map>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "scm/core/city.h"
#include "scm/core/clearance.h"

namespace autodrive::scm {
namespace {

int Run(const std::string& file, const ClearanceCars& cars) {
  const City city = LoadCity(file);
  fmt::print(
      "{}: cars {:.3f} x {:.3f} m, entering at {:.2f} m/s on the last instant of yellow, "
      "the cross car at {:.2f} m/s from its stop line at its green\n",
      city.config.name, cars.length_m, cars.width_m, cars.entering_speed_mps,
      cars.starting_speed_mps);
  int meetings = 0;
  for (const auto& x : city.intersections) {
    for (std::size_t p = 0; p < x.plans.size(); ++p) {
      if (x.plans[p].phases.empty()) continue;  // flash, dark
      const auto cases = MeasureClearances(city.map, x, MeasuredIntergreens(x, p), cars);
      // The worst pair of movements of each pair of groups.
      std::map<std::pair<std::string, std::string>, const ClearanceCase*> worst;
      for (const auto& c : cases) {
        auto& w = worst[{c.ending_group, c.starting_group}];
        if (w == nullptr || c.min_gap_m < w->min_gap_m) w = &c;
      }
      fmt::print("  {} plan {}:\n", x.name, x.plans[p].name);
      for (const auto& [groups, c] : worst) {
        fmt::print("    {:>10} -> {:<10} intergreen {:5.2f} s  closest {:6.3f} m  {}\n",
                   groups.first, groups.second, ToSeconds(c->intergreen), c->min_gap_m,
                   c->meet ? fmt::format("MEET {:.2f} s into the green ({} against {})",
                                         c->meet_after_s, c->ending_movement, c->starting_movement)
                           : std::string("clear"));
        meetings += c->meet ? 1 : 0;
      }
    }
  }
  fmt::print("{} pairs of groups whose cars meet\n", meetings);
  return meetings == 0 ? 0 : 1;
}

}  // namespace
}  // namespace autodrive::scm

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-bench-clearance: do a car entering on the last instant of yellow and a cross "
      "car starting on its green meet, with a city's timings? (docs/scm.md, \"Clearances\"); "
      "exits 1 when some do"};
  std::string city;
  autodrive::scm::ClearanceCars cars;
  app.add_option("city", city, "city file")->required()->check(CLI::ExistingFile);
  app.add_option("--entering-speed", cars.entering_speed_mps,
                 "m/s of the car that enters on yellow (a Nigel's top: 0.26)")
      ->check(CLI::Range(0.01, 50.0));
  app.add_option("--starting-speed", cars.starting_speed_mps,
                 "m/s of the cross car as it crosses its stop line")
      ->check(CLI::Range(0.01, 50.0));
  app.add_option("--length", cars.length_m, "the cars' length, m")->check(CLI::Range(0.01, 20.0));
  app.add_option("--width", cars.width_m, "the cars' width, m")->check(CLI::Range(0.01, 20.0));
  CLI11_PARSE(app, argc, argv);
  try {
    return autodrive::scm::Run(city, cars);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-bench-clearance: %s\n", e.what());
    return 2;
  }
}
