// autodrive-example-parking-plan: the parking case study's global planner (hybrid A* over
// Reeds–Shepp's forward and reverse arcs, examples/parking/hybrid_astar.h) on a map's occupancy
// grid, from a start pose to a goal pose (rear axle, map frame); prints the path's length, its
// gear changes and the search's size, and with --png draws it on the map. See README.md.
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "examples/parking/hybrid_astar.h"
#include "maps/map_io.h"
#include "maps/occupancy.h"
#include "maps/render.h"

namespace {

using namespace autodrive;

RigidTransform2 ParsePose(const std::vector<double>& v, const char* what) {
  if (v.size() != 3) throw InputError(std::string(what) + ": give X,Y,YAW (m, m, rad)");
  return RigidTransform2::FromXyYaw(v[0], v[1], v[2]);
}

void Draw(const maps::Map& map, const examples::PlanResult& plan,
          const examples::HybridAStarParams& p, const std::string& path) {
  maps::RenderOptions o;
  o.pixels_per_tile = 200;
  const maps::Picture picture = maps::RenderPicture(map, o);
  cv::Mat rgb(picture.height_px, picture.width_px, CV_8UC3,
              const_cast<std::uint8_t*>(picture.rgb.data()));
  cv::Mat image;
  cv::cvtColor(rgb, image, cv::COLOR_RGB2BGR);
  const auto px = [&](const Eigen::Vector2d& q) {
    const Eigen::Vector2d u = maps::MapToPixel(map, o, q);
    return cv::Point(static_cast<int>(std::lround(u.x())), static_cast<int>(std::lround(u.y())));
  };
  const auto body = [&](const RigidTransform2& X, const cv::Scalar& colour) {
    std::vector<cv::Point> corners;
    for (const auto& [u, v] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
      corners.push_back(
          px(X * Eigen::Vector2d(p.centre_ahead_m + u * p.length_m / 2, v * p.width_m / 2)));
    }
    cv::polylines(image, corners, true, colour, 2, cv::LINE_AA);
  };
  for (std::size_t i = 1; i < plan.path.size(); ++i) {
    const cv::Scalar colour =
        plan.path[i].gear > 0 ? cv::Scalar(200, 80, 0) : cv::Scalar(0, 0, 220);
    cv::line(image, px(plan.path[i - 1].X_MV.translation()), px(plan.path[i].X_MV.translation()),
             colour, 3, cv::LINE_AA);
  }
  if (!plan.path.empty()) {
    body(plan.path.front().X_MV, cv::Scalar(0, 160, 0));
    body(plan.path.back().X_MV, cv::Scalar(0, 0, 0));
  }
  if (!cv::imwrite(path, image)) throw InputError("cannot write " + path);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-example-parking-plan: plans a car-like path that may reverse (hybrid A* over "
      "Reeds-Shepp's arcs) on a map's occupancy grid, from --from to --to (rear-axle poses "
      "X,Y,YAW in the map frame); prints its length, gear changes and the search's size; "
      "--png draws it (forward blue, backward red). See examples/parking/README.md."};
  std::string map_path, png;
  std::vector<double> from, to;
  double resolution = 0.025;
  examples::HybridAStarParams params;
  app.add_option("--map", map_path, "map file")->required()->check(CLI::ExistingFile);
  app.add_option("--from", from, "start pose X,Y,YAW (m, m, rad)")->required()->delimiter(',');
  app.add_option("--to", to, "goal pose X,Y,YAW (m, m, rad)")->required()->delimiter(',');
  app.add_option("--resolution", resolution, "the occupancy grid's cell (m)")
      ->check(CLI::Range(0.005, 0.2))
      ->capture_default_str();
  app.add_option("--margin", params.margin_m, "kept clear around the body (m)")
      ->check(CLI::Range(0.0, 0.5))
      ->capture_default_str();
  app.add_option("--png", png, "draw the path on the map into this PNG");
  CLI11_PARSE(app, argc, argv);
  try {
    const maps::Map map = maps::LoadMapOrLayout(map_path);
    const examples::HybridAStar planner(maps::MakeOccupancyGrid(map, resolution, false), params);
    const auto t0 = std::chrono::steady_clock::now();
    const examples::PlanResult plan =
        planner.Plan(ParsePose(from, "--from"), ParsePose(to, "--to"));
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (plan.path.empty()) {
      std::fprintf(stderr, "autodrive-example-parking-plan: %s (%zu expansions, %.0f ms)\n",
                   plan.failure.c_str(), plan.expansions, ms);
      return 1;
    }
    const RigidTransform2& end = plan.path.back().X_MV;
    const RigidTransform2 goal = ParsePose(to, "--to");
    std::printf(
        "path: %zu poses, %.2f m, %d gear changes; ends %.1f mm and %.2f deg from the goal; "
        "%zu expansions in %.0f ms\n",
        plan.path.size(), plan.length_m, plan.gear_changes,
        (end.translation() - goal.translation()).norm() * 1000,
        std::abs(WrapAngle(end.yaw() - goal.yaw())) * 180 / 3.14159265358979, plan.expansions, ms);
    if (!png.empty()) Draw(map, plan, params, png);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-example-parking-plan: %s\n", e.what());
    return 1;
  }
}
