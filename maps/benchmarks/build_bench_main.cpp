// Build time of grid cities of N x N intersections, and how it grows with the number of
// intersections (goal: roughly linear; 32 x 32 under 30 s on one core).
#include <chrono>
#include <cstdio>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/logging.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "maps/map_io.h"

int main(int argc, char** argv) {
  CLI::App app{"Build time of N x N grid cities (maps/ builder), printed with the growth ratio"};
  std::vector<int> sizes{2, 8, 32};
  int repeats = 1;
  app.add_option("--sizes", sizes, "grid sizes N (N x N intersections)");
  app.add_option("--repeats", repeats, "builds per size (the fastest counts)")
      ->check(CLI::PositiveNumber);
  std::string log_level = "warn";
  app.add_option("--log-level", log_level, "debug shows the time of each build phase");
  CLI11_PARSE(app, argc, argv);
  autodrive::InitLogging("autodrive-bench-map-build", autodrive::ParseLogLevel(log_level));
  std::printf("%-8s %8s %8s %10s %12s %12s %14s\n", "grid", "tiles", "lanes", "movements",
              "build (s)", "per x (ms)", "growth/linear");
  double first_per = 0;
  for (int n : sizes) {
    const auto layout = autodrive::maps::GridCity(n, n, "mixed");
    double best = 1e300;
    autodrive::maps::MapSummary s;
    for (int r = 0; r < repeats; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      const auto map = autodrive::maps::Build(layout);
      best = std::min(best,
                      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      s = autodrive::maps::Summarise(map);
    }
    const double per = best / (n * n) * 1000;
    if (first_per == 0) first_per = per;
    std::printf("%3dx%-4d %8d %8d %10d %12.3f %12.2f %14.2f\n", n, n, s.rows * s.cols, s.lanes,
                s.movements, best, per, per / first_per);
    std::fflush(stdout);
  }
  return 0;
}
