#include "examples/parking/tracker.h"

#include <algorithm>
#include <cmath>

namespace autodrive::examples {

PathTracker::PathTracker(const TrackerParams& params) : params_(params) {}

void PathTracker::SetPath(const std::vector<PathPose>& path) {
  segments_.clear();
  segment_ = nearest_ = 0;
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (i == 0 || (i > 1 && path[i].gear != path[i - 1].gear)) {
      Segment s;
      s.gear = i == 0 ? path[std::min<std::size_t>(1, path.size() - 1)].gear : path[i].gear;
      if (i > 0) s.poses.push_back(path[i - 1].X_MV);  // the pose where the gear changes
      segments_.push_back(std::move(s));
    }
    segments_.back().poses.push_back(path[i].X_MV);
  }
}

std::vector<PathPose> PathTracker::Ahead() const {
  std::vector<PathPose> out;
  for (std::size_t k = segment_; k < segments_.size(); ++k) {
    const Segment& s = segments_[k];
    for (std::size_t i = k == segment_ ? nearest_ : 0; i < s.poses.size(); ++i) {
      out.push_back({s.poses[i], s.gear});
    }
  }
  return out;
}

TrackCommand PathTracker::Step(const RigidTransform2& X, double speed_mps) {
  TrackCommand c;
  if (segments_.empty()) {
    c.done = true;
    return c;
  }
  const Segment& s = segments_[segment_];
  const Eigen::Vector2d p = X.translation();
  // The nearest pose, searched a little ahead of the last.
  for (std::size_t i = nearest_; i < std::min(s.poses.size(), nearest_ + 20); ++i) {
    if ((s.poses[i].translation() - p).norm() < (s.poses[nearest_].translation() - p).norm()) {
      nearest_ = i;
    }
  }
  const RigidTransform2& end = s.poses.back();
  const Eigen::Vector2d end_dir(std::cos(end.yaw()), std::sin(end.yaw()));
  // Distance left to the segment's end: along the path from the nearest pose, and, close to
  // the end, along the end pose's heading in the direction of travel (it may overshoot a little:
  // then it is negative, and the end is reached).
  double along_left = 0.0;
  for (std::size_t i = nearest_ + 1; i < s.poses.size(); ++i) {
    along_left += (s.poses[i].translation() - s.poses[i - 1].translation()).norm();
  }
  const bool near_end = along_left < params_.lookahead_m;
  const double left = near_end ? (end.translation() - p).dot(end_dir) * s.gear : along_left;
  const bool last = segment_ + 1 == segments_.size();
  if (near_end && left <= params_.arrive_m) {
    c.throttle = 0.0;
    if (speed_mps < params_.stand_mps) {
      if (last) {
        c.done = true;
      } else {
        ++segment_;
        nearest_ = 0;
      }
    }
    return c;
  }
  // The look-ahead point: along the path, then on along the end pose's heading.
  double along = 0.0;
  Eigen::Vector2d target = end.translation() + end_dir * s.gear * params_.lookahead_m;
  for (std::size_t i = nearest_ + 1; i < s.poses.size(); ++i) {
    along += (s.poses[i].translation() - s.poses[i - 1].translation()).norm();
    if (along >= params_.lookahead_m) {
      target = s.poses[i].translation();
      break;
    }
  }
  if (along < params_.lookahead_m) {
    target = end.translation() + end_dir * s.gear * (params_.lookahead_m - along);
  }
  const Eigen::Vector2d local = X.inverse() * target;
  const double d2 = std::max(local.squaredNorm(), 1e-6);
  const double curvature = 2 * local.y() / d2;
  c.steering = std::clamp(std::atan(curvature * params_.wheelbase_m) / params_.steering_limit_rad,
                          -1.0, 1.0);
  const double speed = std::clamp(params_.cruise_throttle * left / params_.slow_down_m,
                                  params_.creep_throttle, params_.cruise_throttle);
  c.throttle = s.gear * speed;
  return c;
}

}  // namespace autodrive::examples
