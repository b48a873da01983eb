#include "maps/builder.h"

#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Polygon_with_holes_2.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>

#include <Eigen/Geometry>

#include "common/error.h"
#include "maps/polyline.h"

namespace autodrive::maps {

char SideLetter(Side side) { return "ENWS"[static_cast<int>(side)]; }

std::string TileIndex::Name() const {
  return "r" + std::to_string(row) + "c" + std::to_string(col);
}

std::string_view ToString(Turn turn) {
  switch (turn) {
    case Turn::kStraight:
      return "straight";
    case Turn::kLeft:
      return "left";
    case Turn::kRight:
      return "right";
    case Turn::kUTurn:
      return "u_turn";
  }
  return "?";
}

namespace {
auto FindHead(const std::vector<SignalHead>& heads, SignalHeadId id) {
  return std::lower_bound(heads.begin(), heads.end(), id,
                          [](const SignalHead& h, SignalHeadId i) { return h.id < i; });
}
}  // namespace

const SignalHead& Map::signal_head(SignalHeadId id) const {
  const auto it = FindHead(signal_heads, id);
  if (it == signal_heads.end() || it->id != id) {
    throw std::out_of_range("the map has no signal head " + std::to_string(id.value()));
  }
  return *it;
}

bool Map::HasSignalHead(SignalHeadId id) const {
  const auto it = FindHead(signal_heads, id);
  return it != signal_heads.end() && it->id == id;
}

std::string Map::DescribeSignalHead(SignalHeadId id) const {
  const std::string head = "signal_" + std::to_string(id.value());
  if (!HasSignalHead(id)) return head + " (not in map " + name + ")";
  const SignalHead& h = signal_head(id);
  const Intersection& x = intersection(h.intersection);
  for (const Approach& a : x.approaches) {
    if (a.id == h.approach) {
      return head + " (" + x.name + ", " + std::string(1, SideLetter(a.side)) + " approach)";
    }
  }
  return head + " (" + x.name + ")";
}

bool Map::Conflict(MovementId a, MovementId b) const {
  if (b < a) std::swap(a, b);
  const auto& c = intersection(movement(a).intersection).conflicts;
  return std::find(c.begin(), c.end(), std::pair{a, b}) != c.end();
}

namespace {

using Epick = CGAL::Exact_predicates_inexact_constructions_kernel;
using Epeck = CGAL::Exact_predicates_exact_constructions_kernel;
using Vec = Eigen::Vector2d;

// ---- Sides and tiles ------------------------------------------------------------------------

// The road sides of a module in its own frame, and the pairs of sides its lanes connect
// (a == b: a turning loop entered and left through the same side).
struct ModuleShape {
  std::vector<Side> sides;
  std::vector<std::pair<Side, Side>> connections;
};

ModuleShape ShapeOf(ModuleType type) {
  using S = Side;
  switch (type) {
    case ModuleType::kEmpty:
    case ModuleType::kOpen:
      return {};
    case ModuleType::kStraight:
    case ModuleType::kRamp:
      return {{S::kWest, S::kEast}, {{S::kWest, S::kEast}}};
    case ModuleType::kCurve:
      return {{S::kSouth, S::kEast}, {{S::kSouth, S::kEast}}};
    case ModuleType::kIntersection:
      return {{S::kEast, S::kNorth, S::kWest, S::kSouth}, {}};
    case ModuleType::kTJunction:
      return {{S::kWest, S::kEast, S::kSouth}, {}};
    case ModuleType::kRoadEnd:
      return {{S::kWest}, {{S::kWest, S::kWest}}};
    case ModuleType::kParking:
      return {{S::kSouth}, {{S::kSouth, S::kSouth}}};
  }
  return {};
}

bool IsJunction(ModuleType t) {
  return t == ModuleType::kIntersection || t == ModuleType::kTJunction;
}

struct TileInfo {
  TileIndex index;
  Cell cell;
  int lanes = 1;
  double width = 0.3;  // lane width (m)
  Vec centre;
  std::vector<Side> road_sides;                    // world frame
  std::vector<std::pair<Side, Side>> connections;  // world frame
  bool HasRoad(Side s) const {
    return std::find(road_sides.begin(), road_sides.end(), s) != road_sides.end();
  }
  std::string Describe() const {
    return "tile " + index.Name() + " (row " + std::to_string(index.row) + ", column " +
           std::to_string(index.col) + ", \"" + cell.ToConfigString() + "\")";
  }
};

[[noreturn]] void Fail(const std::string& message) { throw InputError(message); }

// ---- Paths ----------------------------------------------------------------------------------

void AppendArc(Polyline& out, const Vec& centre, double radius, double a0, double sweep,
               double step) {
  const int n = std::max(2, static_cast<int>(std::ceil(std::abs(sweep) * radius / step)));
  for (int i = out.empty() ? 0 : 1; i <= n; ++i) {
    const double a = a0 + sweep * i / n;
    out.push_back(centre + radius * Vec(std::cos(a), std::sin(a)));
  }
}

void AppendLine(Polyline& out, const Vec& a, const Vec& b, double step) {
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / step)));
  for (int i = out.empty() ? 0 : 1; i <= n; ++i) out.push_back(a + (b - a) * (double(i) / n));
}

double Angle(const Vec& v) { return std::atan2(v.y(), v.x()); }

// The shorter arc about `centre` from `p` to `q` (|p - centre| == |q - centre|).
Polyline ShortArc(const Vec& centre, const Vec& p, const Vec& q, double step) {
  const double a0 = Angle(p - centre);
  const double sweep = WrapAngle(Angle(q - centre) - a0);
  Polyline out;
  AppendArc(out, centre, (p - centre).norm(), a0, sweep, step);
  out.back() = q;
  return out;
}

// A path from `p` heading `dp` to `q` heading `dq` when the two headings are perpendicular:
// a circular arc when p and q are equally far from the corner where their lines meet,
// otherwise a cubic Bezier.
Polyline TurnPath(const Vec& p, const Vec& dp, const Vec& q, const Vec& dq, double step) {
  // Corner: p + dp * s == q - dq * t.
  Eigen::Matrix2d A;
  A << dp, dq;
  const Vec st = A.colPivHouseholderQr().solve(q - p);
  const Vec corner = p + dp * st.x();
  const Vec centre = corner + (q - corner) + (p - corner);  // the circle's centre
  if (std::abs((p - centre).norm() - (q - centre).norm()) < 1e-9) {
    return ShortArc(centre, p, q, step);
  }
  const double L = 0.55 * (q - p).norm();
  const Vec c1 = p + dp * L;
  const Vec c2 = q - dq * L;
  const int n = std::max(4, static_cast<int>(std::ceil((q - p).norm() * 1.6 / step)));
  Polyline out;
  for (int i = 0; i <= n; ++i) {
    const double t = double(i) / n;
    const double u = 1 - t;
    out.push_back(u * u * u * p + 3 * u * u * t * c1 + 3 * u * t * t * c2 + t * t * t * q);
  }
  return out;
}

// A turning loop (Dubins right-left-right) from `p` heading `d` back to `q` heading `-d`,
// every arc of radius `r`. Returns nullopt when p and q are too far apart for radius r.
std::optional<Polyline> LoopPath(const Vec& p, const Vec& q, const Vec& d, double r, double step) {
  const Vec c1 = p + RightOf(d) * r;
  const Vec c3 = q + RightOf(-d) * r;
  const double half = (c1 - c3).norm() / 2;
  if (half > 2 * r) return std::nullopt;
  const Vec c2 = (c1 + c3) / 2 + d * std::sqrt(4 * r * r - half * half);
  const Vec t1 = (c1 + c2) / 2;
  const Vec t2 = (c2 + c3) / 2;
  Polyline out;
  const double a1 = Angle(p - c1);
  double s1 = Angle(t1 - c1) - a1;  // clockwise: negative sweep
  while (s1 > 0) s1 -= 2 * kPi;
  AppendArc(out, c1, r, a1, s1, step);
  const double a2 = Angle(t1 - c2);
  double s2 = Angle(t2 - c2) - a2;  // counter-clockwise, the long way round
  while (s2 <= 0) s2 += 2 * kPi;
  AppendArc(out, c2, r, a2, s2, step);
  const double a3 = Angle(t2 - c3);
  double s3 = Angle(q - c3) - a3;
  while (s3 > 0) s3 -= 2 * kPi;
  AppendArc(out, c3, r, a3, s3, step);
  out.front() = p;
  out.back() = q;
  return out;
}

double Length(const Polyline& p) {
  double l = 0;
  for (std::size_t i = 1; i < p.size(); ++i) l += (p[i] - p[i - 1]).norm();
  return l;
}

// Left and right boundaries at half-width `h` from a centreline.
void Boundaries(const Polyline& c, double h, Polyline& left, Polyline& right) {
  left.clear();
  right.clear();
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec a = c[i == 0 ? 0 : i - 1];
    const Vec b = c[i + 1 < c.size() ? i + 1 : i];
    const Vec t = (b - a).normalized();
    left.push_back(c[i] + LeftOf(t) * h);
    right.push_back(c[i] + RightOf(t) * h);
  }
}

// ---- CGAL helpers ---------------------------------------------------------------------------

CGAL::Polygon_2<Epeck> ToPolygon(const Polyline& ring) {
  CGAL::Polygon_2<Epeck> poly;
  for (const auto& p : ring) poly.push_back(Epeck::Point_2(p.x(), p.y()));
  if (poly.is_clockwise_oriented()) poly.reverse_orientation();
  return poly;
}

Polyline FromPolygon(const CGAL::Polygon_2<Epeck>& poly) {
  Polyline out;
  for (auto v = poly.vertices_begin(); v != poly.vertices_end(); ++v) {
    out.emplace_back(CGAL::to_double(v->x()), CGAL::to_double(v->y()));
  }
  return out;
}

// Simple polygons covering a strip of half-width h along a path: one polygon when that is
// simple, else chunks short enough to be simple (a turning loop comes back near itself).
// Every `stride`-th point is used (the surface needs less detail than the lanes).
void StripPolygons(const Polyline& path, double h, std::size_t stride,
                   std::vector<CGAL::Polygon_2<Epeck>>& out) {
  Polyline c;
  for (std::size_t i = 0; i < path.size(); i += stride) c.push_back(path[i]);
  if (c.back() != path.back()) c.push_back(path.back());
  Polyline left, right;
  Boundaries(c, h, left, right);
  const auto strip = [&](std::size_t s, std::size_t e) {
    Polyline ring(left.begin() + static_cast<long>(s), left.begin() + static_cast<long>(e) + 1);
    for (std::size_t i = e + 1; i-- > s;) ring.push_back(right[i]);
    return ToPolygon(ring);
  };
  if (auto whole = strip(0, c.size() - 1); whole.is_simple()) {
    out.push_back(std::move(whole));
    return;
  }
  const std::size_t chunk = 6;
  for (std::size_t s = 0; s + 1 < c.size(); s += chunk) {
    auto poly = strip(s, std::min(c.size() - 1, s + chunk));
    if (poly.is_simple()) out.push_back(std::move(poly));
  }
}

Polyline Rectangle(const Vec& centre, double yaw, double length, double width) {
  const Vec u(std::cos(yaw), std::sin(yaw));
  const Vec v = LeftOf(u);
  return {centre - u * length / 2 - v * width / 2, centre + u * length / 2 - v * width / 2,
          centre + u * length / 2 + v * width / 2, centre - u * length / 2 + v * width / 2};
}

// True when two polylines come closer than sqrt(limit2) (crossing included).
bool CloserThan(const Polyline& a, const Polyline& b, double limit2) {
  const auto box = [](const Polyline& p) {
    Eigen::AlignedBox2d bb;
    for (const auto& q : p) bb.extend(q);
    return bb;
  };
  const Eigen::AlignedBox2d ba = box(a), bb = box(b);
  if (ba.squaredExteriorDistance(bb) >= limit2) return false;
  for (std::size_t i = 1; i < a.size(); ++i) {
    Eigen::AlignedBox2d sa(a[i - 1]);
    sa.extend(a[i]);
    if (sa.squaredExteriorDistance(bb) >= limit2) continue;
    const Epick::Segment_2 sega({a[i - 1].x(), a[i - 1].y()}, {a[i].x(), a[i].y()});
    for (std::size_t j = 1; j < b.size(); ++j) {
      Eigen::AlignedBox2d sb(b[j - 1]);
      sb.extend(b[j]);
      if (sa.squaredExteriorDistance(sb) >= limit2) continue;
      const Epick::Segment_2 segb({b[j - 1].x(), b[j - 1].y()}, {b[j].x(), b[j].y()});
      if (CGAL::squared_distance(sega, segb) < limit2) return true;
    }
  }
  return false;
}

// Points keyed on a 1 micrometre grid, to join lanes end to start.
using PointKey = std::pair<long long, long long>;
PointKey Key(const Vec& p) { return {std::llround(p.x() * 1e6), std::llround(p.y() * 1e6)}; }

// ---- The builder ----------------------------------------------------------------------------

class Builder {
 public:
  Builder(const Layout& layout, const BuildOptions& options) : layout_(layout), o_(options) {}

  Map Build() {
    layout_.Validate();
    map_.layout = layout_;
    map_.options = o_;
    map_.name = layout_.name;
    map_.tile_size_m = layout_.tile_size_m;
    map_.lane_width_m = layout_.lane_width_m;
    map_.rows = static_cast<int>(layout_.grid.size());
    map_.cols = static_cast<int>(layout_.grid.front().size());
    map_.cells = layout_.grid;
    auto t0 = std::chrono::steady_clock::now();
    const auto phase = [&](const char* name) {
      const auto t1 = std::chrono::steady_clock::now();
      spdlog::debug("map {}: {} took {:.3f} s", layout_.name, name,
                    std::chrono::duration<double>(t1 - t0).count());
      t0 = t1;
    };
    MakeTiles();
    CheckEdges();
    phase("tiles and edges");
    MakeLanes();
    JoinLanes();
    phase("lanes");
    MakeIntersections();
    phase("intersections and conflicts");
    MakeObstacles();
    MakeSigns();
    phase("obstacles and signs");
    MakeSurfaces();
    phase("road surface and drivable area");
    MakeTerrain();
    return std::move(map_);
  }

 private:
  double T() const { return layout_.tile_size_m; }
  TileInfo* TileAt(int r, int c) {
    if (r < 0 || c < 0 || r >= map_.rows || c >= map_.cols) return nullptr;
    return &tiles_[static_cast<std::size_t>(r * map_.cols + c)];
  }
  TileInfo* Neighbour(const TileInfo& t, Side s) {
    const Vec o = Outward(s);
    return TileAt(t.index.row - static_cast<int>(o.y()), t.index.col + static_cast<int>(o.x()));
  }
  Vec Mid(const TileInfo& t, Side s) const { return t.centre + Outward(s) * T() / 2; }
  // Where lane k (counted from the centreline) crosses side s of tile t, for a lane entering
  // (inward) or leaving (outward) through that side.
  Vec LanePoint(const TileInfo& t, Side s, int k, bool entering) const {
    const Vec d = entering ? Vec(-Outward(s)) : Outward(s);
    return Mid(t, s) + RightOf(d) * (k + 0.5) * t.width;
  }

  void MakeTiles() {
    for (int r = 0; r < map_.rows; ++r) {
      for (int c = 0; c < map_.cols; ++c) {
        TileInfo t;
        t.index = {r, c};
        t.cell = layout_.grid[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
        t.lanes = t.cell.lanes.value_or(layout_.lanes_per_direction);
        t.width = t.cell.lane_width_m.value_or(layout_.lane_width_m);
        t.centre = map_.TileCentre(t.index);
        const int k = t.cell.rotation_deg / 90;
        const ModuleShape shape = ShapeOf(t.cell.type);
        for (Side s : shape.sides) t.road_sides.push_back(Rotate(s, k));
        for (auto [a, b] : shape.connections) t.connections.push_back({Rotate(a, k), Rotate(b, k)});
        if ((t.cell.type == ModuleType::kRoadEnd || t.cell.type == ModuleType::kParking) &&
            t.lanes != 1) {
          Fail(t.Describe() + ": a turning loop has one lane per direction, not " +
               std::to_string(t.lanes));
        }
        tiles_.push_back(t);
      }
    }
  }

  void CheckEdges() {
    for (auto& t : tiles_) {
      for (Side s : t.road_sides) {
        TileInfo* n = Neighbour(t, s);
        const std::string edge = std::string(1, SideLetter(s)) + " edge";
        if (n == nullptr) {
          if (IsJunction(t.cell.type)) {
            Fail(t.Describe() + ": its " + edge +
                 " is the map boundary; an intersection arm needs a road tile beyond it");
          }
          continue;  // a road may leave the map
        }
        if (!n->HasRoad(Opposite(s))) {
          Fail(t.Describe() + ": its road on the " + edge + " meets " + n->Describe() +
               ", which has no road on its " + SideLetter(Opposite(s)) +
               " edge (mismatched tile edges)");
        }
        if (n->lanes != t.lanes) {
          Fail(t.Describe() + ": " + std::to_string(t.lanes) + " lane(s) per direction on its " +
               edge + " but " + n->Describe() + " has " + std::to_string(n->lanes));
        }
        if (std::abs(n->width - t.width) > 1e-9) {
          Fail(t.Describe() + ": lanes " + Num(t.width) + " m wide on its " + edge + " but " +
               n->Describe() + " has lanes " + Num(n->width) + " m wide");
        }
        if (IsJunction(t.cell.type) && IsJunction(n->cell.type)) {
          Fail(t.Describe() + ": next to another intersection, " + n->Describe() +
               "; put a road tile between them");
        }
        CheckHeights(t, s, *n);
      }
    }
  }

  // The ground's height along side s of tile t (ramps rise along their local +x).
  double EdgeHeight(const TileInfo& t, Side s) const {
    if (t.cell.type != ModuleType::kRamp) return t.cell.elevation_m;
    const Side high = Rotate(Side::kEast, t.cell.rotation_deg / 90);
    if (s == high) return t.cell.elevation_m + t.cell.rise_m;
    if (s == Opposite(high)) return t.cell.elevation_m;
    return t.cell.elevation_m + t.cell.rise_m / 2;
  }

  void CheckHeights(const TileInfo& t, Side s, const TileInfo& n) const {
    const double a = EdgeHeight(t, s);
    const double b = EdgeHeight(n, Opposite(s));
    if (std::abs(a - b) > 1e-9) {
      std::ostringstream msg;
      msg << t.Describe() << ": its road on the " << SideLetter(s) << " edge is at " << a
          << " m but " << n.Describe() << " is at " << b << " m there (mismatched heights)";
      Fail(msg.str());
    }
  }

  LaneId AddLane(const TileInfo& t, Side from, Side to, int k, Polyline centreline) {
    Lane lane;
    lane.id = LaneId(static_cast<std::uint32_t>(map_.lanes.size() + 1));
    lane.name =
        t.index.Name() + ":" + SideLetter(from) + ">" + SideLetter(to) + ":" + std::to_string(k);
    lane.tile = t.index;
    lane.from_side = from;
    lane.to_side = to;
    lane.width_m = t.width;
    lane.index_from_centre = k;
    lane.centreline = std::move(centreline);
    Boundaries(lane.centreline, t.width / 2, lane.left_boundary, lane.right_boundary);
    lane.length_m = Length(lane.centreline);
    map_.lanes.push_back(std::move(lane));
    return map_.lanes.back().id;
  }

  void MakeLanes() {
    for (const auto& t : tiles_) {
      for (auto [a, b] : t.connections) {
        if (a == b) {
          const Vec p = LanePoint(t, a, 0, true);
          const Vec q = LanePoint(t, a, 0, false);
          auto loop = LoopPath(p, q, -Outward(a), o_.min_turn_radius_m, o_.sample_step_m);
          if (!loop) {
            Fail(t.Describe() + ": the turning loop does not fit lanes " + Num(t.width) +
                 " m wide with a turning radius of " + std::to_string(o_.min_turn_radius_m) + " m");
          }
          AddLane(t, a, a, 0, std::move(*loop));
          continue;
        }
        for (int dir = 0; dir < 2; ++dir) {
          const Side from = dir == 0 ? a : b;
          const Side to = dir == 0 ? b : a;
          for (int k = 0; k < t.lanes; ++k) {
            const Vec p = LanePoint(t, from, k, true);
            const Vec q = LanePoint(t, to, k, false);
            Polyline c;
            if (to == Opposite(from)) {
              AppendLine(c, p, q, o_.sample_step_m);
            } else {
              c = TurnPath(p, -Outward(from), q, Outward(to), o_.sample_step_m);
            }
            AddLane(t, from, to, k, std::move(c));
          }
        }
      }
    }
  }

  void JoinLanes() {
    for (const auto& lane : map_.lanes) {
      starts_[Key(lane.centreline.front())].push_back(lane.id);
      ends_[Key(lane.centreline.back())].push_back(lane.id);
    }
    for (auto& lane : map_.lanes) {
      if (auto it = starts_.find(Key(lane.centreline.back())); it != starts_.end()) {
        for (LaneId next : it->second) {
          lane.successors.push_back(next);
          map_.lanes[next.value() - 1].predecessors.push_back(lane.id);
        }
      }
    }
  }

  LaneId FindLane(const std::map<PointKey, std::vector<LaneId>>& index, const Vec& p,
                  const TileInfo& t, Side s) {
    const auto it = index.find(Key(p));
    AUTODRIVE_CHECK(it != index.end() && it->second.size() == 1,
                    "no single lane at " << p.transpose() << " on side " << SideLetter(s) << " of "
                                         << t.index.Name());
    return it->second.front();
  }

  void MakeIntersections() {
    for (const auto& t : tiles_) {
      if (!IsJunction(t.cell.type)) continue;
      Intersection x;
      x.id = IntersectionId(static_cast<std::uint32_t>(map_.intersections.size() + 1));
      x.name = t.cell.name.empty() ? "x_" + t.index.Name() : t.cell.name;
      x.tile = t.index;
      x.control = t.cell.control;
      x.centre = t.centre;
      for (Side s : {Side::kEast, Side::kNorth, Side::kWest, Side::kSouth}) {
        if (!t.HasRoad(s)) continue;
        Approach a;
        a.side = s;
        a.id = ApproachId(static_cast<std::uint32_t>(s) + 1);
        a.ingress_heading_rad = Angle(-Outward(s));
        for (int k = 0; k < t.lanes; ++k) {
          const LaneId in = FindLane(ends_, LanePoint(t, s, k, true), t, s);
          const LaneId out = FindLane(starts_, LanePoint(t, s, k, false), t, s);
          a.ingress.push_back(in);
          a.egress.push_back(out);
          Lane& lin = map_.lanes[in.value() - 1];
          lin.ingress_of = x.id;
          lin.ingress_approach = a.id;
          if (x.control != Control::kUncontrolled) {
            const Vec e = lin.centreline.back();
            const Vec d = -Outward(s);
            lin.stop_line = StopLine{e + LeftOf(d) * t.width / 2, e + RightOf(d) * t.width / 2};
          }
          Lane& lout = map_.lanes[out.value() - 1];
          lout.egress_of = x.id;
          lout.egress_approach = a.id;
        }
        x.approaches.push_back(a);
      }
      for (const auto& from : x.approaches) {
        for (const auto& to : x.approaches) {
          if (from.side == to.side) continue;
          const int rel = (static_cast<int>(to.side) - static_cast<int>(from.side) + 4) % 4;
          const Turn turn = rel == 2 ? Turn::kStraight : rel == 1 ? Turn::kRight : Turn::kLeft;
          std::vector<std::pair<int, int>> pairs;
          if (turn == Turn::kStraight) {
            for (int k = 0; k < t.lanes; ++k) pairs.push_back({k, k});
          } else if (turn == Turn::kRight) {
            pairs.push_back({t.lanes - 1, t.lanes - 1});
          } else {
            pairs.push_back({0, 0});
          }
          for (auto [ki, ko] : pairs) AddMovement(x, t, from, to, turn, ki, ko);
        }
      }
      ComputeConflicts(x);
      if (x.control == Control::kSignal) AddSignalHeads(x, t);
      map_.intersections.push_back(std::move(x));
    }
    NumberSignalHeads();
  }

  void AddMovement(Intersection& x, const TileInfo& t, const Approach& from, const Approach& to,
                   Turn turn, int ki, int ko) {
    Movement m;
    m.id = MovementId(static_cast<std::uint32_t>(map_.movements.size() + 1));
    m.intersection = x.id;
    m.from = from.ingress[static_cast<std::size_t>(ki)];
    m.to = to.egress[static_cast<std::size_t>(ko)];
    m.from_approach = from.id;
    m.to_approach = to.id;
    m.turn = turn;
    m.name = t.index.Name() + ":" + SideLetter(from.side) + ">" + SideLetter(to.side) + ":" +
             std::to_string(ki) + ">" + std::to_string(ko);
    const Vec p = map_.lanes[m.from.value() - 1].centreline.back();
    const Vec q = map_.lanes[m.to.value() - 1].centreline.front();
    if (turn == Turn::kStraight) {
      AppendLine(m.path, p, q, o_.sample_step_m);
    } else {
      m.path = TurnPath(p, -Outward(from.side), q, Outward(to.side), o_.sample_step_m);
    }
    m.length_m = Length(m.path);
    map_.lanes[m.from.value() - 1].movements_out.push_back(m.id);
    map_.lanes[m.to.value() - 1].movements_in.push_back(m.id);
    x.movements.push_back(m.id);
    map_.movements.push_back(std::move(m));
  }

  void ComputeConflicts(Intersection& x) {
    const double clearance2 = o_.vehicle_clearance_m * o_.vehicle_clearance_m;
    for (std::size_t i = 0; i < x.movements.size(); ++i) {
      for (std::size_t j = i + 1; j < x.movements.size(); ++j) {
        const Movement& a = map_.movements[x.movements[i].value() - 1];
        const Movement& b = map_.movements[x.movements[j].value() - 1];
        bool conflict;
        if (a.from == b.from) {
          conflict = false;  // diverging from one lane: one vehicle at a time, by rule
        } else if (a.to == b.to) {
          conflict = true;  // merging into one lane
        } else {
          conflict = CloserThan(a.path, b.path, clearance2);  // crossing or too close
        }
        if (conflict) x.conflicts.push_back({a.id, b.id});
      }
    }
  }

  // One head per approach, with the ids the cell gives (heads=FIRST or heads=E4/N5/...), or
  // 0 for NumberSignalHeads to give.
  void AddSignalHeads(Intersection& x, const TileInfo& t) {
    const Cell& cell = t.cell;
    for (const auto& [side, id] : cell.head_by_side) {
      bool found = false;
      for (const auto& a : x.approaches) found = found || SideLetter(a.side) == side;
      if (!found) {
        Fail(t.Describe() + ": heads= gives head " + std::to_string(id) + " to its " +
             std::string(1, side) + " approach, but it has no road on that side");
      }
    }
    std::uint32_t next = cell.first_head.value_or(0);
    for (const auto& a : x.approaches) {
      const Lane& kerb = map_.lanes[a.ingress.back().value() - 1];
      const Vec d = -Outward(a.side);
      // At the corner on the approach's right, just beyond the kerb, facing the traffic.
      const Vec pos = kerb.right_boundary.back() + RightOf(d) * 0.06 + d * 0.06;
      SignalHead h;
      if (cell.first_head) {
        h.id = SignalHeadId(next++);
      } else if (!cell.head_by_side.empty()) {
        const auto it = cell.head_by_side.find(SideLetter(a.side));
        if (it == cell.head_by_side.end()) {
          Fail(t.Describe() + ": heads= gives no id to its " + std::string(1, SideLetter(a.side)) +
               " approach (give every approach one: " + HeadsExample(x) + ")");
        }
        h.id = SignalHeadId(it->second);
      }
      h.intersection = x.id;
      h.approach = a.id;
      h.X_MH = RigidTransform2::FromXyYaw(pos.x(), pos.y(), WrapAngle(Angle(d) + kPi));
      map_.signal_heads.push_back(h);
    }
  }

  static std::string HeadsExample(const Intersection& x) {
    std::string s = "heads=";
    for (std::size_t i = 0; i < x.approaches.size(); ++i) {
      s +=
          (i ? "/" : "") + std::string(1, SideLetter(x.approaches[i].side)) + std::to_string(i + 1);
    }
    return s;
  }

  // Heads without an id from their cell get the next ids above every id a cell gives, in map
  // order, so that giving a new intersection's heads no ids never moves another's. Two heads
  // with one id are refused. Then the heads in ascending id order, and each intersection's in
  // the order of its approaches.
  void NumberSignalHeads() {
    std::uint32_t next = 1;
    for (const SignalHead& h : map_.signal_heads) next = std::max(next, h.id.value() + 1);
    std::map<SignalHeadId, const SignalHead*> seen;
    for (SignalHead& h : map_.signal_heads) {
      if (h.id.value() == 0) h.id = SignalHeadId(next++);
      const auto [it, fresh] = seen.emplace(h.id, &h);
      if (!fresh) {
        Fail("signal head " + std::to_string(h.id.value()) + " is given twice: to intersection " +
             map_.intersection(it->second->intersection).name + " and to " +
             map_.intersection(h.intersection).name + " (heads= of their cells)");
      }
    }
    for (Intersection& x : map_.intersections) x.signal_heads.clear();
    for (const SignalHead& h : map_.signal_heads) {
      map_.intersections[h.intersection.value() - 1].signal_heads.push_back(h.id);
    }
    std::sort(map_.signal_heads.begin(), map_.signal_heads.end(),
              [](const SignalHead& a, const SignalHead& b) { return a.id < b.id; });
  }

  void MakeObstacles() {
    const Vec size = map_.size_m();
    std::vector<ObstacleSpec> specs = layout_.obstacles;
    if (layout_.boundary_walls) {
      const double th = layout_.wall_thickness_m;
      const double hh = layout_.wall_height_m;
      specs.push_back({"wall", size.x() / 2, th / 2, 0, size.x(), th, hh});
      specs.push_back({"wall", size.x() / 2, size.y() - th / 2, 0, size.x(), th, hh});
      specs.push_back({"wall", th / 2, size.y() / 2, kPi / 2, size.y() - 2 * th, th, hh});
      specs.push_back(
          {"wall", size.x() - th / 2, size.y() / 2, kPi / 2, size.y() - 2 * th, th, hh});
    }
    std::vector<CGAL::Polygon_2<Epeck>> polys;
    for (std::size_t i = 0; i < specs.size(); ++i) {
      const auto& s = specs[i];
      Obstacle o;
      o.kind = s.kind;
      o.height_m = s.height_m;
      o.footprint = Rectangle({s.x_m, s.y_m}, s.yaw_rad, s.length_m, s.width_m);
      const std::string what = DescribeObstacle(i, s);
      for (const auto& p : o.footprint) {
        if (p.x() < -1e-9 || p.y() < -1e-9 || p.x() > size.x() + 1e-9 || p.y() > size.y() + 1e-9) {
          Fail(what + " reaches outside the map [0, " + Num(size.x()) + "] x [0, " + Num(size.y()) +
               "] m");
        }
      }
      auto poly = ToPolygon(o.footprint);
      for (std::size_t j = 0; j < polys.size(); ++j) {
        if (CGAL::do_intersect(poly, polys[j])) {
          Fail(what + " overlaps " + DescribeObstacle(j, specs[j]));
        }
      }
      if (s.kind == "wall") CheckWallAgainstRoads(what, poly);
      polys.push_back(poly);
      map_.obstacles.push_back(std::move(o));
    }
  }

  std::string DescribeObstacle(std::size_t i, const ObstacleSpec& s) const {
    if (i >= layout_.obstacles.size()) return "the boundary wall";
    return "obstacle " + std::to_string(i) + " (" + s.kind + " at x " + Num(s.x_m) + ", y " +
           Num(s.y_m) + ")";
  }
  static std::string Num(double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  }

  // A wall across the mouth of a road (where it crosses a tile edge) closes the road.
  void CheckWallAgainstRoads(const std::string& what, const CGAL::Polygon_2<Epeck>& wall) {
    for (const auto& t : tiles_) {
      for (Side s : t.road_sides) {
        const Vec m = Mid(t, s);
        const Vec along = LeftOf(Outward(s)) * (t.lanes * t.width);
        const Vec inward = -Outward(s) * 1e-4;
        const Polyline mouth = {m + along, m - along, m - along + inward, m + along + inward};
        if (CGAL::do_intersect(wall, ToPolygon(mouth))) {
          Fail(what + " closes the road of " + t.Describe() + " at its " + SideLetter(s) +
               " edge (a road that ends in a wall)");
        }
      }
    }
  }

  // A sign given by the layout stands beside the road: its pole on a lane or a path through an
  // intersection would stand in the cars' way (and under a LIDAR's plane, unseen).
  void RefuseOnRoad(const Sign& sign) const {
    const Vec at = sign.X_MS.translation();
    const auto refuse = [&](const std::string& on, double distance, double half_width) {
      Fail(
          fmt::format("sign {} ({}) at ({:.3f}, {:.3f}) stands on {}: {:.3f} m from its centre, "
                      "less than the half width {:.3f} m; signs stand beside the road",
                      sign.id.value(), sign.type, at.x(), at.y(), on, distance, half_width));
    };
    for (const Lane& lane : map_.lanes) {
      const double d = NearestOnPolyline(lane.centreline, at).distance_m;
      if (d < lane.width_m / 2) refuse("lane " + lane.name, d, lane.width_m / 2);
    }
    for (const Movement& m : map_.movements) {
      const double half = map_.lane(m.from).width_m / 2;
      const double d = NearestOnPolyline(m.path, at).distance_m;
      if (d < half) refuse("the path " + m.name, d, half);
    }
  }

  void MakeSigns() {
    for (const auto& s : layout_.signs) {
      Sign sign;
      sign.id = SignId(static_cast<std::uint32_t>(map_.signs.size() + 1));
      sign.type = s.type;
      sign.X_MS = RigidTransform2::FromXyYaw(s.x_m, s.y_m, s.yaw_rad);
      sign.value = s.value;
      RefuseOnRoad(sign);
      map_.signs.push_back(sign);
    }
    // Stop and yield signs of controlled intersections, one per approach at its right corner.
    for (const auto& x : map_.intersections) {
      if (x.control != Control::kStop && x.control != Control::kYield) continue;
      for (const auto& a : x.approaches) {
        const Lane& kerb = map_.lanes[a.ingress.back().value() - 1];
        const Vec d = -Outward(a.side);
        const Vec pos = kerb.right_boundary.back() + RightOf(d) * 0.06 - d * 0.02;
        Sign sign;
        sign.id = SignId(static_cast<std::uint32_t>(map_.signs.size() + 1));
        sign.type = x.control == Control::kStop ? "stop" : "yield";
        sign.X_MS = RigidTransform2::FromXyYaw(pos.x(), pos.y(), WrapAngle(Angle(d) + kPi));
        sign.lane = a.ingress.back();
        map_.signs.push_back(sign);
      }
    }
  }

  // The road surface is the union, per tile, of lane and movement strips and open or parking
  // floors; every piece lies inside its tile, so tiles are joined independently (linear in the
  // number of tiles) and the regions of neighbouring tiles meet along tile edges.
  void MakeSurfaces() {
    const std::size_t stride =
        std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(0.05 / o_.sample_step_m)));
    std::vector<std::vector<CGAL::Polygon_2<Epeck>>> pieces(tiles_.size());
    const auto tile_of = [&](const TileIndex& i) {
      return static_cast<std::size_t>(i.row * map_.cols + i.col);
    };
    for (const auto& lane : map_.lanes) {
      StripPolygons(lane.centreline, lane.width_m / 2, stride, pieces[tile_of(lane.tile)]);
    }
    for (const auto& m : map_.movements) {
      StripPolygons(m.path, map_.lane(m.from).width_m / 2, stride,
                    pieces[tile_of(map_.intersection(m.intersection).tile)]);
    }
    for (const auto& t : tiles_) {
      const double h = T() / 2;
      if (t.cell.type == ModuleType::kOpen || t.cell.type == ModuleType::kParking) {
        pieces[tile_of(t.index)].push_back(ToPolygon(Rectangle(t.centre, 0, 2 * h, 2 * h)));
      }
      if (t.cell.type != ModuleType::kParking) continue;
      // Bays along the side opposite the entrance.
      const Side back = Opposite(t.road_sides.front());
      const Vec out = Outward(back);
      const Vec along = LeftOf(out);
      const double depth = std::min(0.45, 0.4 * T());
      const double width = 0.3;
      const int n = static_cast<int>(std::floor(T() / width));
      for (int i = 0; i < n; ++i) {
        const Vec c = t.centre + out * (h - depth / 2) + along * ((i - (n - 1) / 2.0) * width);
        map_.parking_bays.push_back({t.index.Name() + ":bay" + std::to_string(i + 1),
                                     Rectangle(c, Angle(along), width, depth)});
      }
    }
    for (const auto& t : tiles_) {
      auto& tile_pieces = pieces[tile_of(t.index)];
      if (tile_pieces.empty()) continue;
      CGAL::Polygon_set_2<Epeck> road;
      road.join(tile_pieces.begin(), tile_pieces.end());
      for (auto& r : ToRegions(road)) map_.road_surface.push_back(std::move(r));
      Eigen::AlignedBox2d tile_box(t.centre - Vec(T(), T()) / 2, t.centre + Vec(T(), T()) / 2);
      for (const auto& o : map_.obstacles) {
        Eigen::AlignedBox2d ob;
        for (const auto& p : o.footprint) ob.extend(p);
        if (ob.intersects(tile_box)) road.difference(ToPolygon(o.footprint));
      }
      for (auto& r : ToRegions(road)) map_.drivable.push_back(std::move(r));
    }
  }

  static std::vector<Region> ToRegions(const CGAL::Polygon_set_2<Epeck>& set) {
    std::vector<CGAL::Polygon_with_holes_2<Epeck>> pwhs;
    set.polygons_with_holes(std::back_inserter(pwhs));
    std::vector<Region> out;
    for (const auto& pwh : pwhs) {
      Region r;
      r.outer = FromPolygon(pwh.outer_boundary());
      for (auto h = pwh.holes_begin(); h != pwh.holes_end(); ++h)
        r.holes.push_back(FromPolygon(*h));
      out.push_back(std::move(r));
    }
    return out;
  }

  void MakeTerrain() {
    map_.terrain.rows = map_.rows;
    map_.terrain.cols = map_.cols;
    for (const auto& t : tiles_) {
      map_.terrain.tile_elevation_m.push_back(t.cell.elevation_m);
      map_.terrain.tile_rise_m.push_back(t.cell.type == ModuleType::kRamp ? t.cell.rise_m : 0.0);
      map_.terrain.tile_rotation_deg.push_back(t.cell.rotation_deg);
    }
  }

  const Layout& layout_;
  const BuildOptions o_;
  Map map_;
  std::vector<TileInfo> tiles_;
  std::map<PointKey, std::vector<LaneId>> starts_;
  std::map<PointKey, std::vector<LaneId>> ends_;
};

}  // namespace

Map Build(const Layout& layout, const BuildOptions& options) {
  return Builder(layout, options).Build();
}

}  // namespace autodrive::maps
