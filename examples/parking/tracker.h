#pragma once
/// @file
/// The parking case study's path-tracking controller: follows a planned path (rear-axle poses
/// with their gear) segment by segment, a segment being a stretch in one gear. Pure pursuit on
/// the rear axle (the arc through the look-ahead point tangent to the car's heading: curvature
/// 2y / d², the same formula forwards and backwards), its steering the bicycle model's
/// atan(curvature x wheelbase); the throttle falls with the distance left in the segment down
/// to a creep, and is zero at the segment's end until the car stands, when it changes gear.
/// Past the last pose the look-ahead point runs on along the end pose's heading, so the car
/// settles onto the goal's line.

#include <string>
#include <vector>

#include "common/config.h"
#include "common/geometry.h"
#include "examples/parking/hybrid_astar.h"

namespace autodrive::examples {

struct TrackerParams {
  double wheelbase_m = 0.14154;
  double steering_limit_rad = 0.5236;
  double lookahead_m = 0.12;
  double cruise_throttle = 0.5;
  double creep_throttle = 0.2;
  double slow_down_m = 0.25;  ///< the throttle falls over this distance to a segment's end
  double arrive_m = 0.008;    ///< a segment's end is reached this close (along its heading)
  double stand_mps = 0.005;   ///< standing: slower than this

  /// The tunables (the car's figures come from its city). See examples/parking/parking.yaml.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("lookahead_m", lookahead_m, config::Range{0.01, 2.0});
    a.Optional("cruise_throttle", cruise_throttle, config::Range{0.05, 1.0});
    a.Optional("creep_throttle", creep_throttle, config::Range{0.01, 1.0});
    a.Optional("slow_down_m", slow_down_m, config::Range{0.0, 5.0});
    a.Optional("arrive_m", arrive_m, config::Range{0.0005, 0.5});
    a.Optional("stand_mps", stand_mps, config::Range{0.0001, 0.5});
  }
};

struct TrackCommand {
  double throttle = 0.0;  ///< normalised, negative backwards
  double steering = 0.0;  ///< normalised, positive left
  bool done = false;      ///< at the path's end, standing
};

class PathTracker {
 public:
  explicit PathTracker(const TrackerParams& params = {});
  /// Starts on `path` (from the car's present pose).
  void SetPath(const std::vector<PathPose>& path);
  /// The command for the car at rear-axle pose `X` moving at `speed_mps` (unsigned).
  [[nodiscard]] TrackCommand Step(const RigidTransform2& X, double speed_mps);
  /// The poses of the path not driven yet (the segment under way from its nearest pose on).
  [[nodiscard]] std::vector<PathPose> Ahead() const;
  [[nodiscard]] std::size_t segment() const { return segment_; }
  [[nodiscard]] std::size_t segments() const { return segments_.size(); }

 private:
  struct Segment {
    std::vector<RigidTransform2> poses;
    int gear = 1;
  };
  TrackerParams params_;
  std::vector<Segment> segments_;
  std::size_t segment_ = 0;
  std::size_t nearest_ = 0;
};

}  // namespace autodrive::examples
