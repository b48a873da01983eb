#include "scm/core/clearance.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "scm/core/controller.h"

namespace autodrive::scm {

namespace {

/// A point or vector of the plane. The measurement below evaluates millions of footprints for a
/// shipped city; with plain doubles it takes a second under the sanitizers' Debug build, where
/// Eigen's expression templates, unoptimised, took two minutes.
struct P {
  double x = 0.0, y = 0.0;
  P operator+(P o) const { return {x + o.x, y + o.y}; }
  P operator-(P o) const { return {x - o.x, y - o.y}; }
  P operator*(double k) const { return {x * k, y * k}; }
  [[nodiscard]] double dot(P o) const { return x * o.x + y * o.y; }
  [[nodiscard]] double norm() const { return std::hypot(x, y); }
};
using Corners = std::array<P, 4>;

/// A lane-following path: the approach lane, the movement through the box, the exit lane; arc
/// length 0 at the stop line, extended straight beyond both ends.
class Path {
 public:
  Path(const maps::Map& map, const maps::Movement& m) {
    const auto& in = map.lane(m.from).centreline;
    const auto& out = map.lane(m.to).centreline;
    for (const auto& p : in) Add(p);
    stop_line_ = arc_.back();
    for (const auto& p : m.path) Add(p);
    for (const auto& p : out) Add(p);
  }
  /// The point at `s` metres from the stop line.
  [[nodiscard]] P At(double s) const {
    const double a = s + stop_line_;
    // The first point at or past `a`, or the last (the path goes on straight past its ends).
    const auto first = std::lower_bound(arc_.begin() + 1, arc_.end() - 1, a);
    const auto i = static_cast<std::size_t>(first - arc_.begin());
    const double t = (a - arc_[i - 1]) / (arc_[i] - arc_[i - 1]);
    return points_[i - 1] + (points_[i] - points_[i - 1]) * t;
  }

 private:
  void Add(const Eigen::Vector2d& v) {
    const P p{v.x(), v.y()};
    if (!points_.empty() && (p - points_.back()).norm() < 1e-9) return;
    arc_.push_back(points_.empty() ? 0.0 : arc_.back() + (p - points_.back()).norm());
    points_.push_back(p);
  }
  std::vector<P> points_;
  std::vector<double> arc_;
  double stop_line_ = 0.0;
};

/// The footprint of a car whose front is at `s` on `path`, its rear `length` behind on it.
Corners Footprint(const Path& path, double s, const ClearanceCars& cars) {
  const P front = path.At(s);
  const P rear = path.At(s - cars.length_m);
  const P centre = (front + rear) * 0.5;
  P x = front - rear;
  const double n = x.norm();
  x = n > 1e-9 ? x * (1.0 / n) : P{1.0, 0.0};
  const P y{-x.y, x.x};
  const P hx = x * (cars.length_m / 2.0);
  const P hy = y * (cars.width_m / 2.0);
  return {centre + hx + hy, centre - hx + hy, centre - hx - hy, centre + hx - hy};
}

/// True when the convex quadrilaterals overlap (separating axis test).
bool Overlap(const Corners& a, const Corners& b) {
  for (const Corners* poly : {&a, &b}) {
    for (std::size_t i = 0; i < 4; ++i) {
      const P e = (*poly)[(i + 1) % 4] - (*poly)[i];
      const P n{-e.y, e.x};
      double amin = std::numeric_limits<double>::max(), amax = -amin;
      double bmin = amin, bmax = -amin;
      for (const auto& p : a) amin = std::min(amin, n.dot(p)), amax = std::max(amax, n.dot(p));
      for (const auto& p : b) bmin = std::min(bmin, n.dot(p)), bmax = std::max(bmax, n.dot(p));
      if (amax < bmin || bmax < amin) return false;
    }
  }
  return true;
}

double PointSegment(P p, P a, P b) {
  const P d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.dot(d), 0.0, 1.0);
  return (p - (a + d * t)).norm();
}

/// The distance between two quadrilaterals, 0 when they overlap.
double Gap(const Corners& a, const Corners& b) {
  if (Overlap(a, b)) return 0.0;
  double gap = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < 4; ++i) {
    for (std::size_t j = 0; j < 4; ++j) {
      gap = std::min(gap, PointSegment(a[i], b[j], b[(j + 1) % 4]));
      gap = std::min(gap, PointSegment(b[i], a[j], a[(j + 1) % 4]));
    }
  }
  return gap;
}

std::string Label(const SignalGroup& g) { return fmt::format("{} ({})", g.id.value(), g.name); }

}  // namespace

std::vector<std::vector<std::optional<Duration>>> MeasuredIntergreens(const IntersectionModel& x,
                                                                      std::size_t plan) {
  const std::size_t n = x.groups.size();
  const MonoTime start(std::chrono::hours(1000));
  IntersectionController controller(x, start, Mode::kAuto, plan);
  controller.SetDevicesReady(true);
  const std::vector<bool> calls(n, true);
  std::vector<std::vector<MonoTime>> yellow_end(n), green_start(n);
  std::vector<Aspect> last = controller.aspects();
  const Duration tick = std::chrono::milliseconds(10);
  // Start-up, then two long cycles at the least (every green at its max).
  const MonoTime end = start + std::chrono::minutes(10);
  for (MonoTime now = start + tick; now <= end; now += tick) {
    controller.Step(now, calls, DayClock::At(std::chrono::hours(12)));
    const auto& aspects = controller.aspects();
    for (std::size_t g = 0; g < n; ++g) {
      if (last[g] == Aspect::kYellow && aspects[g] != Aspect::kYellow) yellow_end[g].push_back(now);
      if (last[g] != Aspect::kGreen && aspects[g] == Aspect::kGreen) green_start[g].push_back(now);
    }
    last = aspects;
  }
  std::vector<std::vector<std::optional<Duration>>> out(n, std::vector<std::optional<Duration>>(n));
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = 0; b < n; ++b) {
      if (!x.conflicts[a][b]) continue;
      for (const MonoTime t : yellow_end[a]) {
        const auto next = std::ranges::upper_bound(green_start[b], t);
        if (next == green_start[b].end()) continue;
        const Duration d = *next - t;
        if (!out[a][b] || d < *out[a][b]) out[a][b] = d;
      }
    }
  }
  return out;
}

std::vector<ClearanceCase> MeasureClearances(
    const maps::Map& map, const IntersectionModel& x,
    const std::vector<std::vector<std::optional<Duration>>>& intergreens,
    const ClearanceCars& cars) {
  std::vector<ClearanceCase> out;
  const double dt = 0.005;
  for (std::size_t a = 0; a < x.groups.size(); ++a) {
    for (std::size_t b = 0; b < x.groups.size(); ++b) {
      if (!intergreens[a][b]) continue;
      const double intergreen = ToSeconds(*intergreens[a][b]);
      for (const MovementId ma : x.groups[a].movements) {
        for (const MovementId mb : x.groups[b].movements) {
          if (!map.Conflict(ma, mb)) continue;
          const Path pa(map, map.movement(ma));
          const Path pb(map, map.movement(mb));
          ClearanceCase c{Label(x.groups[a]),    Label(x.groups[b]),
                          map.movement(ma).name, map.movement(mb).name,
                          *intergreens[a][b],    std::numeric_limits<double>::max()};
          // Time from the end of A's yellow, when A's front is on its stop line; until both
          // cars' rears are past the box.
          const double box_a = map.movement(ma).length_m + cars.length_m;
          const double box_b = map.movement(mb).length_m + cars.length_m;
          const double until = std::max(box_a / cars.entering_speed_mps,
                                        intergreen + box_b / cars.starting_speed_mps);
          // From the conflicting green on: before it the cross car waits behind its stop line.
          for (double t = intergreen; t <= until; t += dt) {
            const double sa = cars.entering_speed_mps * t;
            const double sb = cars.starting_speed_mps * (t - intergreen);
            const double gap = Gap(Footprint(pa, sa, cars), Footprint(pb, sb, cars));
            c.min_gap_m = std::min(c.min_gap_m, gap);
            if (gap == 0.0 && !c.meet) {
              c.meet = true;
              c.meet_after_s = t - intergreen;
            }
          }
          out.push_back(std::move(c));
        }
      }
    }
  }
  return out;
}

}  // namespace autodrive::scm
