#pragma once
/// @file
/// What the SCM's benchmark programs (autodrive-bench-scm, autodrive-soak-scm) share: the grid
/// city they run, a process's CPU time and resident memory, percentiles.
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/process.h"
#include "maps/builder.h"
#include "maps/grid_city.h"

namespace autodrive::bench {

/// The `p` quantile (0..1) of `v`, nearest rank; 0 when empty.
inline double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(p * static_cast<double>(v.size() - 1) + 0.5);
  return v[std::min(i, v.size() - 1)];
}

/// utime + stime of a process, seconds.
inline double CpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = text.rfind(')');
  if (close == std::string::npos) return 0.0;
  std::istringstream fields(text.substr(close + 2));
  std::string f;
  double ticks = 0;
  for (int i = 3; i <= 15; ++i) {
    fields >> f;
    if (i == 14 || i == 15) ticks += std::stod(f);
  }
  return ticks / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

/// A /proc/PID/status field in kB (VmRSS, VmHWM, ...); 0 when absent.
inline double StatusKb(pid_t pid, const std::string& field) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1));
  }
  return 0.0;
}

/// A sibling program of the running one (build/bin/NAME).
inline std::string Bin(const std::string& name) {
  return (std::filesystem::path(ExecutableDir()) / name).string();
}

/// The source tree (the programs run from build/bin).
inline std::filesystem::path Source() {
  return std::filesystem::canonical(std::filesystem::path(ExecutableDir()) / "../..");
}

/// Writes a grid city of n x n fixed-time intersections without lights into `dir`, for operator
/// `operator_name`: four groups (east, north, west, south), one per phase, 8 s green each, so no
/// two groups of an intersection may be green or yellow together. Returns the city file.
inline std::filesystem::path WriteGridCity(int n, const std::filesystem::path& dir,
                                           const std::string& operator_name = "bench") {
  const maps::Layout layout = maps::GridCity(n, n, "signal");
  config::SaveFile(layout, (dir / "grid.yaml").string());
  const maps::Map map = maps::Build(layout);
  std::string city =
      "name: grid\nmap: grid.yaml\ndevices: {wait_for_lights: false}\n"
      "operators: {allowed: [" +
      operator_name + "]}\nintersections:\n";
  for (const auto& x : map.intersections) {
    city += "  - name: " + x.name +
            "\n    groups: [{id: 1, name: e, approaches: [east]}, {id: 2, name: n, approaches: "
            "[north]}, {id: 3, name: w, approaches: [west]}, {id: 4, name: s, approaches: "
            "[south]}]\n    plans: [{name: day, phases: [{groups: [1], green_s: 8.0}, {groups: "
            "[2], green_s: 8.0}, {groups: [3], green_s: 8.0}, {groups: [4], green_s: 8.0}]}]\n";
  }
  const std::filesystem::path path = dir / "grid_city.yaml";
  std::ofstream(path) << city;
  return path;
}

}  // namespace autodrive::bench
