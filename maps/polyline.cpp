#include "maps/polyline.h"

#include <algorithm>
#include <cmath>

namespace autodrive::maps {

PolylinePoint NearestOnPolyline(const Polyline& line, const Eigen::Vector2d& p) {
  PolylinePoint best;
  double at = 0;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double n = d.norm();
    if (n <= 0) continue;
    const double t = std::clamp((p - line[i]).dot(d) / (n * n), 0.0, 1.0);
    const Eigen::Vector2d q = line[i] + t * d;
    const double distance = (q - p).norm();
    if (distance < best.distance_m) {
      best.point = q;
      best.along_m = at + t * n;
      best.distance_m = distance;
      best.direction_rad = std::atan2(d.y(), d.x());
    }
    at += n;
  }
  best.length_m = at;
  return best;
}

std::pair<Eigen::Vector2d, double> PointAlong(const Polyline& line, double along) {
  along = std::max(along, 0.0);
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector2d d = line[i] - line[i - 1];
    const double n = d.norm();
    if (n <= 0) continue;
    if (along <= n || i + 1 == line.size()) {
      return {line[i - 1] + d * std::min(along, n) / n, std::atan2(d.y(), d.x())};
    }
    along -= n;
  }
  return {line.empty() ? Eigen::Vector2d::Zero() : line.back(), 0.0};
}

double PolylineLength(const Polyline& line) {
  double s = 0.0;
  for (std::size_t i = 1; i < line.size(); ++i) s += (line[i] - line[i - 1]).norm();
  return s;
}

}  // namespace autodrive::maps
