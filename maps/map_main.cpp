// autodrive-map: builds a lab's map from a layout and writes everything the other components
// need; prints a map's summary; generates grid-city layouts.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include <CLI/CLI.hpp>

#include "common/config.h"
#include "common/logging.h"
#include "maps/builder.h"
#include "maps/grid_city.h"
#include "maps/lane_graph.h"
#include "maps/map_io.h"
#include "maps/mesh.h"
#include "maps/outputs.h"

namespace fs = std::filesystem;
using namespace autodrive::maps;

namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

int Info(const std::string& path, bool lanes) {
  const Map map = LoadMapOrLayout(path);
  const MapSummary s = Summarise(map);
  std::printf("map %s: %d x %d tiles of %.3g m (%.3g m x %.3g m), lanes %.3g m wide\n",
              map.name.c_str(), map.rows, map.cols, map.tile_size_m, map.size_m().x(),
              map.size_m().y(), map.lane_width_m);
  std::printf("  lanes %d, movements %d, conflicts %d, signal heads %d, signs %d, obstacles %d\n",
              s.lanes, s.movements, s.conflicts, s.signal_heads, s.signs, s.obstacles);
  std::printf("  road surface %.3f m2, drivable %.3f m2, parking bays %zu\n", s.road_area_m2,
              s.drivable_area_m2, map.parking_bays.size());
  std::printf("  intersections %d\n", s.intersections);
  for (const auto& x : map.intersections) {
    std::printf("    %-28s %-6s %s at (%.3f, %.3f): %zu approaches, %zu movements, %zu conflicts\n",
                x.name.c_str(), x.tile.Name().c_str(), std::string(ToString(x.control)).c_str(),
                x.centre.x(), x.centre.y(), x.approaches.size(), x.movements.size(),
                x.conflicts.size());
    if (!x.signal_heads.empty()) {
      // The heads' ids, which the lights files list and a real track is wired by.
      std::string heads;
      for (const auto& a : x.approaches) {
        for (const autodrive::SignalHeadId h : x.signal_heads) {
          if (map.signal_head(h).approach == a.id) {
            heads += (heads.empty() ? "" : ", ") + std::string(1, SideLetter(a.side)) + ": " +
                     autodrive::SignalHeadName(h);
          }
        }
      }
      std::printf("      signal heads by approach: %s\n", heads.c_str());
    }
  }
  const auto problems = CheckReachability(map);
  std::printf("  reachability: %s\n",
              problems.empty() ? "every lane reaches and is reached from the boundary or a loop"
                               : (std::to_string(problems.size()) + " problems").c_str());
  for (const auto& p : problems) std::printf("    %s\n", p.c_str());
  if (lanes) {
    // What a route (a scenario's, the example driver's --route) is made of: each lane, where
    // it ends, and what may follow it.
    std::printf("  lanes (name: length; at its end; then):\n");
    for (const auto& lane : map.lanes) {
      std::string next;
      for (const auto id : lane.successors) next += " " + map.lane(id).name;
      for (const auto id : lane.movements_out) {
        const auto& m = map.movement(id);
        next += " " + map.lane(m.to).name + " (" + std::string(ToString(m.turn)) + ")";
      }
      std::string end = "open";
      if (lane.ingress_of) {
        const auto& x = map.intersection(*lane.ingress_of);
        end = std::string(x.control == Control::kSignal ? "signal at " : "stop at ") + x.name;
      }
      std::printf("    %s: %.3f m; %s; then%s\n", lane.name.c_str(), lane.length_m, end.c_str(),
                  next.empty() ? " nothing" : next.c_str());
    }
  }
  return problems.empty() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"autodrive-map: builds a lab's map from a layout of modules (see docs/maps.md)"};
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off");

  auto* build = app.add_subcommand("build", "build a map from a layout and write its outputs");
  std::string layout_path;
  std::string out_dir;
  OutputOptions outputs;
  build->add_option("layout", layout_path, "layout YAML")->required()->check(CLI::ExistingFile);
  build->add_option("-o,--output", out_dir, "output directory (created)")->required();
  build
      ->add_option("--resolution", outputs.occupancy_resolution_m,
                   "occupancy grid resolution, m/pixel")
      ->check(CLI::Range(0.005, 1.0));
  build->add_flag("!--no-sumo", outputs.sumo, "do not write the SUMO network");
  build->add_flag("!--no-images", outputs.images, "do not write the PNG and SVG pictures");

  auto* info = app.add_subcommand("info", "print a summary of a map (map.yaml or a layout)");
  std::string map_path;
  info->add_option("map", map_path, "map.yaml or layout YAML")
      ->required()
      ->check(CLI::ExistingFile);
  bool list_lanes = false;
  info->add_flag("--lanes", list_lanes,
                 "also list every lane: its length, the intersection at its end and the lanes "
                 "that may follow it (for routes)");

  auto* grid = app.add_subcommand("grid", "write the layout of a grid city of R x C intersections");
  int rows = 2, cols = 2;
  std::string control = "mixed";
  std::string grid_out;
  grid->add_option("rows", rows, "rows of intersections")->required();
  grid->add_option("cols", cols, "columns of intersections")->required();
  grid->add_option("--control", control, "signal | stop | mixed")
      ->check(CLI::IsMember({"signal", "stop", "mixed"}));
  grid->add_option("-o,--output", grid_out, "layout YAML to write")->required();

  CLI11_PARSE(app, argc, argv);
  try {
    autodrive::InitLogging("autodrive-map", autodrive::ParseLogLevel(log_level));
    if (*info) return Info(map_path, list_lanes);
    if (*grid) {
      autodrive::config::SaveFile(GridCity(rows, cols, control), grid_out);
      std::printf("wrote %s (%d x %d intersections, %d x %d tiles)\n", grid_out.c_str(), rows, cols,
                  2 * rows + 1, 2 * cols + 1);
      return 0;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const Map map = Build(LoadLayout(layout_path));
    std::printf("built %s in %.2f s: %s\n", map.name.c_str(), Seconds(t0),
                Summarise(map).ToString().c_str());
    fs::create_directories(out_dir);
    for (const auto& file : WriteOutputs(map, out_dir, outputs)) {
      std::printf("  wrote %s\n", file.c_str());
    }
    const auto problems = CheckReachability(map);
    for (const auto& p : problems) std::fprintf(stderr, "warning: %s\n", p.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-map: %s\n", e.what());
    return 1;
  }
}
