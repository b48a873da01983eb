#include "maps/query.h"

#include <CGAL/AABB_segment_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <vector>

#include <Eigen/Geometry>

namespace autodrive::maps {

namespace {
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Segment3 = K::Segment_3;
using SegmentIterator = std::vector<Segment3>::const_iterator;
using Primitive = CGAL::AABB_segment_primitive<K, SegmentIterator>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
}  // namespace

struct MapIndex::Impl {
  // Centreline segments embedded in z = 0 (CGAL 5.5's AABB tree is three-dimensional).
  std::vector<Segment3> segments;
  std::vector<std::pair<std::size_t, std::size_t>> owner;  // (lane index, segment index)
  std::vector<std::vector<double>> along;                  // per lane: arc length at each point
  Tree tree;
  struct Area {
    CGAL::Polygon_2<K> outer;
    std::vector<CGAL::Polygon_2<K>> holes;
    Eigen::AlignedBox2d box;
  };
  std::vector<Area> areas;
};

MapIndex::MapIndex(const Map& map) : map_(map), impl_(std::make_unique<Impl>()) {
  for (std::size_t l = 0; l < map.lanes.size(); ++l) {
    const auto& c = map.lanes[l].centreline;
    std::vector<double> s{0.0};
    for (std::size_t i = 1; i < c.size(); ++i) {
      impl_->segments.emplace_back(K::Point_3(c[i - 1].x(), c[i - 1].y(), 0),
                                   K::Point_3(c[i].x(), c[i].y(), 0));
      impl_->owner.push_back({l, i - 1});
      s.push_back(s.back() + (c[i] - c[i - 1]).norm());
    }
    impl_->along.push_back(std::move(s));
  }
  impl_->tree.insert(impl_->segments.cbegin(), impl_->segments.cend());
  impl_->tree.build();
  if (!impl_->segments.empty()) impl_->tree.accelerate_distance_queries();
  for (const auto& r : map.drivable) {
    Impl::Area a;
    for (const auto& p : r.outer) {
      a.outer.push_back(K::Point_2(p.x(), p.y()));
      a.box.extend(p);
    }
    for (const auto& h : r.holes) {
      CGAL::Polygon_2<K> hole;
      for (const auto& p : h) hole.push_back(K::Point_2(p.x(), p.y()));
      a.holes.push_back(std::move(hole));
    }
    impl_->areas.push_back(std::move(a));
  }
}

MapIndex::~MapIndex() = default;

std::optional<LaneMatch> MapIndex::NearestLane(const Eigen::Vector2d& p_M,
                                               double max_distance_m) const {
  if (impl_->segments.empty()) return std::nullopt;
  const K::Point_3 q(p_M.x(), p_M.y(), 0);
  const auto [closest, it] = impl_->tree.closest_point_and_primitive(q);
  const Eigen::Vector2d point(closest.x(), closest.y());
  const double d = (point - p_M).norm();
  if (d > max_distance_m) return std::nullopt;
  const auto index = static_cast<std::size_t>(it - impl_->segments.cbegin());
  const auto [lane, seg] = impl_->owner[index];
  const auto& c = map_.lanes[lane].centreline;
  LaneMatch m;
  m.lane = map_.lanes[lane].id;
  m.distance_m = d;
  m.point = point;
  m.along_m = impl_->along[lane][seg] + (point - c[seg]).norm();
  return m;
}

std::optional<LaneMatch> MapIndex::NearestLaneHeading(const Eigen::Vector2d& p_M, double yaw_rad,
                                                      double max_distance_m,
                                                      double max_angle_rad) const {
  const Eigen::Vector2d heading(std::cos(yaw_rad), std::sin(yaw_rad));
  const double min_cos = std::cos(max_angle_rad);
  const K::Iso_cuboid_3 box(p_M.x() - max_distance_m, p_M.y() - max_distance_m, -1.0,
                            p_M.x() + max_distance_m, p_M.y() + max_distance_m, 1.0);
  std::vector<SegmentIterator> near;
  impl_->tree.all_intersected_primitives(box, std::back_inserter(near));
  std::optional<LaneMatch> best;
  for (const SegmentIterator it : near) {
    const Eigen::Vector2d a(it->source().x(), it->source().y());
    const Eigen::Vector2d b(it->target().x(), it->target().y());
    const Eigen::Vector2d ab = b - a;
    const double n = ab.norm();
    if (n <= 0 || ab.dot(heading) < min_cos * n) continue;
    const double t = std::clamp((p_M - a).dot(ab) / (n * n), 0.0, 1.0);
    const Eigen::Vector2d point = a + t * ab;
    const double d = (point - p_M).norm();
    if (d > max_distance_m || (best && d >= best->distance_m)) continue;
    const auto [lane, seg] = impl_->owner[static_cast<std::size_t>(it - impl_->segments.cbegin())];
    best = LaneMatch{map_.lanes[lane].id, d, impl_->along[lane][seg] + t * n, point};
  }
  return best;
}

bool MapIndex::IsDrivable(const Eigen::Vector2d& p_M) const {
  const K::Point_2 q(p_M.x(), p_M.y());
  for (const auto& a : impl_->areas) {
    if (!a.box.contains(p_M)) continue;
    if (a.outer.bounded_side(q) == CGAL::ON_UNBOUNDED_SIDE) continue;
    bool in_hole = false;
    for (const auto& h : a.holes) {
      if (h.bounded_side(q) == CGAL::ON_BOUNDED_SIDE) in_hole = true;
    }
    if (!in_hole) return true;
  }
  return false;
}

}  // namespace autodrive::maps
