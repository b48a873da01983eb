#include "vehicle_sim/lane_driver.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "common/aspect.h"

namespace autodrive::vehicle_sim {

namespace {

double PolylineLength(const maps::Polyline& p) {
  double length = 0;
  for (std::size_t i = 0; i + 1 < p.size(); ++i) length += (p[i + 1] - p[i]).norm();
  return length;
}

double DistanceToPolyline(const maps::Polyline& p, const Eigen::Vector2d& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < p.size(); ++i) {
    const Eigen::Vector2d d = p[i + 1] - p[i];
    const double n2 = d.squaredNorm();
    const double t = n2 > 0 ? std::clamp((q - p[i]).dot(d) / n2, 0.0, 1.0) : 0.0;
    best = std::min(best, (p[i] + t * d - q).norm());
  }
  return best;
}

}  // namespace

LaneDriver::LaneDriver(const maps::Map& map, const DriverOptions& options)
    : map_(&map), options_(options), rng_(options.seed) {}

double LaneDriver::PieceLength(const Piece& piece) const { return PolylineLength(*piece.path); }

void LaneDriver::Localise(const RigidTransform2& X_MV) {
  // The nearest centreline point whose direction agrees with the car's heading.
  const Eigen::Vector2d p = X_MV.translation();
  double best = std::numeric_limits<double>::infinity();
  const maps::Lane* lane = nullptr;
  for (const maps::Lane& l : map_->lanes) {
    for (std::size_t i = 0; i + 1 < l.centreline.size(); ++i) {
      const Eigen::Vector2d a = l.centreline[i];
      const Eigen::Vector2d d = l.centreline[i + 1] - a;
      if (std::abs(WrapAngle(std::atan2(d.y(), d.x()) - X_MV.yaw())) > 1.0) continue;
      const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
      const double distance = (a + t * d - p).norm();
      if (distance < best) {
        best = distance;
        lane = &l;
      }
    }
  }
  route_.clear();
  if (lane == nullptr) return;
  // On its route (again): make for the lane after this one.
  const auto on_route = std::find(options_.route.begin(), options_.route.end(), lane->id);
  if (on_route != options_.route.end()) {
    route_next_ = static_cast<std::size_t>(on_route - options_.route.begin());
  }
  progress_s_ = 0.0;
  PushLane(*lane, 0.0);
  Extend();
  progress_s_ = Project(p);
}

void LaneDriver::PushLane(const maps::Lane& lane, double start_s) {
  route_.push_back({&lane.centreline, &lane, nullptr, start_s});
  if (NextRouteLane() == lane.id) ++route_next_;
}

std::optional<LaneId> LaneDriver::NextRouteLane() const {
  if (route_next_ >= options_.route.size()) return std::nullopt;
  return options_.route[route_next_];
}

bool LaneDriver::AtRouteEnd() const {
  return options_.stop_at_route_end && !options_.route.empty() &&
         route_next_ >= options_.route.size() && !route_.empty() && route_.back().lane != nullptr &&
         route_.back().lane->id == options_.route.back();
}

void LaneDriver::Extend() {
  const auto end_s = [&] { return route_.back().start_s + PieceLength(route_.back()); };
  while (!route_.empty() && end_s() < progress_s_ + options_.plan_ahead_m && !AtRouteEnd()) {
    const Piece& last = route_.back();
    const double start = end_s();
    if (last.movement != nullptr) {
      PushLane(map_->lane(last.movement->to), start);
      continue;
    }
    const maps::Lane& lane = *last.lane;
    const std::optional<LaneId> next_on_route = NextRouteLane();
    if (!lane.movements_out.empty()) {
      const maps::Movement* chosen = nullptr;
      for (const MovementId id : lane.movements_out) {
        if (map_->movement(id).to == next_on_route) chosen = &map_->movement(id);
      }
      if (chosen == nullptr) {
        std::uniform_int_distribution<std::size_t> pick(0, lane.movements_out.size() - 1);
        chosen = &map_->movement(lane.movements_out[pick(rng_)]);
      }
      route_.push_back({&chosen->path, nullptr, chosen, start});
    } else if (!lane.successors.empty()) {
      const auto on_route = std::find(lane.successors.begin(), lane.successors.end(),
                                      next_on_route.value_or(LaneId{0}));
      if (next_on_route && on_route != lane.successors.end()) {
        PushLane(map_->lane(*on_route), start);
      } else {
        std::uniform_int_distribution<std::size_t> pick(0, lane.successors.size() - 1);
        PushLane(map_->lane(lane.successors[pick(rng_)]), start);
      }
    } else {
      break;  // a dead end: the car stops at its end
    }
  }
  // Forget what lies well behind.
  while (route_.size() > 1 && route_[1].start_s < progress_s_ - 1.0) route_.pop_front();
}

Eigen::Vector2d LaneDriver::PointAt(double s) const {
  for (const Piece& piece : route_) {
    const maps::Polyline& p = *piece.path;
    double at = piece.start_s;
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
      const double n = (p[i + 1] - p[i]).norm();
      if (s <= at + n || (&piece == &route_.back() && i + 2 == p.size())) {
        const double t = n > 0 ? std::clamp((s - at) / n, 0.0, 1.0) : 0.0;
        return p[i] + t * (p[i + 1] - p[i]);
      }
      at += n;
    }
  }
  return route_.back().path->back();
}

double LaneDriver::Project(const Eigen::Vector2d& q) const {
  // The nearest route point within a window around the current progress.
  double best_d = std::numeric_limits<double>::infinity();
  double best_s = progress_s_;
  for (const Piece& piece : route_) {
    const maps::Polyline& p = *piece.path;
    double at = piece.start_s;
    for (std::size_t i = 0; i + 1 < p.size(); ++i) {
      const Eigen::Vector2d d = p[i + 1] - p[i];
      const double n = d.norm();
      if (at + n >= progress_s_ - 0.3 && at <= progress_s_ + 0.6 && n > 0) {
        const double t = std::clamp((q - p[i]).dot(d) / (n * n), 0.0, 1.0);
        const double distance = (p[i] + t * d - q).norm();
        if (distance < best_d) {
          best_d = distance;
          best_s = at + t * n;
        }
      }
      at += n;
    }
  }
  return best_s;
}

bool LaneDriver::BoxClear(const maps::Intersection& x, const RigidTransform2& X_MV,
                          std::span<const float> lidar) const {
  const double half = map_->tile_size_m / 2 - options_.box_margin_m;
  const auto beams = static_cast<double>(lidar.size());
  for (std::size_t i = 0; i < lidar.size(); ++i) {
    const double r = lidar[i];
    if (!std::isfinite(r) || r > 2 * map_->tile_size_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(i) / beams;
    const Eigen::Vector2d p =
        X_MV * Eigen::Vector2d(options_.lidar_x_m + r * std::cos(a), r * std::sin(a));
    const Eigen::Vector2d d = p - x.centre;
    if (std::abs(d.x()) >= half || std::abs(d.y()) >= half) continue;
    // On a path through the box (the poles of its lights and signs stand beside them).
    for (const MovementId m : x.movements) {
      if (DistanceToPolyline(map_->movement(m).path, p) < options_.half_width_m + 0.05) {
        return false;
      }
    }
  }
  return true;
}

double LaneDriver::GapAhead(const RigidTransform2& X_MV, std::span<const float> lidar,
                            double front_s, double range) const {
  const double corridor = options_.half_width_m + options_.path_margin_m;
  const auto beams = static_cast<double>(lidar.size());
  double gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < lidar.size(); ++i) {
    const double r = lidar[i];
    if (!std::isfinite(r) || r > range + options_.front_overhang_m) continue;
    const double a = 2 * std::numbers::pi * static_cast<double>(i) / beams;
    const Eigen::Vector2d q =
        X_MV * Eigen::Vector2d(options_.lidar_x_m + r * std::cos(a), r * std::sin(a));
    // The nearest point of the route ahead of the front (up to `range`), within the corridor.
    for (const Piece& piece : route_) {
      const maps::Polyline& p = *piece.path;
      double at = piece.start_s;
      for (std::size_t k = 0; k + 1 < p.size(); ++k) {
        const Eigen::Vector2d d = p[k + 1] - p[k];
        const double n = d.norm();
        if (n > 0 && at + n >= front_s && at <= front_s + range) {
          const double t = std::clamp((q - p[k]).dot(d) / (n * n), 0.0, 1.0);
          const double s = at + t * n;
          if (s >= front_s && (p[k] + t * d - q).norm() < corridor) {
            gap = std::min(gap, s - front_s);
          }
        }
        at += n;
      }
    }
  }
  return gap;
}

bool LaneDriver::StopSign(double line_s, const maps::Intersection& x, double to_line,
                          const RigidTransform2& X_MV, std::span<const float> lidar, Duration now) {
  if (sign_done_at_s_ == line_s) return false;  // stopped at this line on this pass already
  if (to_line <= options_.stop_gap_m + 0.02) {
    if (!stopped_at_sign_since_) stopped_at_sign_since_ = now;
    if (now - *stopped_at_sign_since_ >= options_.stop_sign_wait && BoxClear(x, X_MV, lidar)) {
      sign_done_at_s_ = line_s;
      stopped_at_sign_since_.reset();
      return false;
    }
  }
  return true;
}

bool LaneDriver::FlashingRed(SignalHeadId h, std::optional<std::int32_t> wire, Duration now) {
  // A head that says it flashes red (wire 4), or one that shows red and dark in turn.
  const std::optional<Aspect> aspect = wire ? AspectFromWire(*wire) : std::nullopt;
  LampSeen& seen = seen_[h];
  if (aspect == Aspect::kFlashingRed) {
    seen = {};
    return true;
  }
  if (aspect == Aspect::kRed) seen.red = now;
  if (aspect == Aspect::kOff) seen.dark = now;
  if (aspect && aspect != Aspect::kRed && aspect != Aspect::kOff) seen = {};
  return seen.red && seen.dark && now - *seen.red <= options_.flash_window &&
         now - *seen.dark <= options_.flash_window;
}

DriverDecision LaneDriver::Step(
    const RigidTransform2& X_MV,
    const std::function<std::optional<std::int32_t>(SignalHeadId)>& lamp,
    std::span<const float> lidar, Duration now) {
  // The lamps of the ingress approach's head, read as an indication with no times.
  const SignalLookup from_lamps = [&](const maps::Lane& ingress,
                                      const maps::Movement*) -> std::optional<SignalIndication> {
    const maps::Intersection& x = map_->intersection(*ingress.ingress_of);
    std::optional<Aspect> shown;
    bool flashing = false;
    for (SignalHeadId h : x.signal_heads) {
      const maps::SignalHead& head = map_->signal_head(h);
      if (head.approach == ingress.ingress_approach) {
        const std::optional<std::int32_t> wire = lamp(h);
        shown = wire ? AspectFromWire(*wire) : std::nullopt;
        flashing = FlashingRed(h, wire, now);
      }
    }
    using State = SignalIndication::State;
    if (flashing) return SignalIndication{State::kFlashingRed, {}, {}, {}};
    if (!shown) return std::nullopt;
    switch (*shown) {
      case Aspect::kGreen:
        return SignalIndication{State::kGreen, {}, {}, {}};
      case Aspect::kYellow:
        return SignalIndication{State::kYellow, {}, {}, {}};
      case Aspect::kFlashingYellow:
        return SignalIndication{State::kFlashingYellow, {}, {}, {}};
      default:  // red, and a dark head not (yet) seen flashing: stop
        return SignalIndication{State::kRed, {}, {}, {}};
    }
  };
  return Step(X_MV, from_lamps, lidar, now);
}

DriverDecision LaneDriver::Step(const RigidTransform2& X_MV, const SignalLookup& signal,
                                std::span<const float> lidar, Duration now,
                                std::optional<double> speed_limit_mps) {
  DriverDecision decision;
  next_line_.reset();
  const Eigen::Vector2d p = X_MV.translation();
  if (route_.empty() || (PointAt(Project(p)) - p).norm() > 0.4) {
    Localise(X_MV);
    last_step_.reset();
  }
  if (route_.empty()) {
    decision.reason = DriverDecision::Reason::kLost;
    return decision;
  }
  progress_s_ = std::max(progress_s_ - 0.05, Project(p));
  Extend();
  // The speed along the route, smoothed over a few steps.
  if (last_step_ && now > *last_step_) {
    const double v = (progress_s_ - last_progress_s_) / ToSeconds(now - *last_step_);
    speed_mps_ += 0.3 * (v - speed_mps_);
  }
  if (!last_step_ || now > *last_step_) {
    last_step_ = now;
    last_progress_s_ = progress_s_;
  }

  // Pure pursuit towards the route point one lookahead ahead.
  Eigen::Vector2d target = PointAt(progress_s_ + options_.lookahead_m);
  if (options_.lateral_offset_m != 0.0) {
    const Eigen::Vector2d along = target - PointAt(progress_s_ + options_.lookahead_m - 0.02);
    if (along.norm() > 1e-6) {
      target += options_.lateral_offset_m * Eigen::Vector2d(-along.y(), along.x()).normalized();
    }
  }
  const Eigen::Vector2d local = X_MV.inverse() * target;
  const double alpha = std::atan2(local.y(), local.x());
  const double delta =
      std::atan2(2 * options_.wheelbase_m * std::sin(alpha), std::max(local.norm(), 0.05));
  decision.steering = std::clamp(delta / options_.steering_limit_rad, -1.0, 1.0);

  // The speed: cruise, unless a stop line or something ahead says otherwise.
  double throttle = options_.cruise_throttle;
  const double front_s = progress_s_ + options_.front_overhang_m;
  for (std::size_t k = 0; k < route_.size(); ++k) {
    const Piece& piece = route_[k];
    if (piece.lane == nullptr || !piece.lane->stop_line || !piece.lane->ingress_of) continue;
    const double line_s = piece.start_s + PieceLength(piece);
    const double to_line = line_s - front_s;
    if (to_line < -0.05) continue;
    const maps::Intersection& x = map_->intersection(*piece.lane->ingress_of);
    const maps::Movement* movement = k + 1 < route_.size() ? route_[k + 1].movement : nullptr;
    next_line_ = StopLineAhead{&x, piece.lane, movement,
                               movement != nullptr ? &map_->lane(movement->to) : nullptr, to_line};
    if (to_line > options_.slow_down_m + options_.stop_gap_m + 0.5) break;
    bool stop = false;
    if (x.control == maps::Control::kSignal && !options_.ignore_lights) {
      using State = SignalIndication::State;
      const std::optional<SignalIndication> shown = signal(*piece.lane, movement);
      const bool as_stop_sign =
          shown && (shown->state == State::kFlashingRed || shown->state == State::kDark);
      const bool go =
          shown && (shown->state == State::kGreen || shown->state == State::kFlashingYellow);
      if (as_stop_sign && !options_.ignore_stop_signs) {
        stop = StopSign(line_s, x, to_line, X_MV, lidar, now);
        if (stop) decision.reason = DriverDecision::Reason::kStopSign;
      } else {
        // (Ignoring stop signs, it rolls through a flashing red as through a stop sign.)
        bool cross_yellow = false;
        if (shown && shown->state == State::kYellow) {
          // Its tail passes the line before the yellow ends, or it cannot stop before the line
          // itself (braking at about 0.5 m/s²; not the stop gap short of it). A car creeping to
          // the line, or standing at it (for a queue beyond the box), stops: it would start
          // across on a yellow it cannot clear.
          const double to_clear = to_line + options_.front_overhang_m + options_.rear_overhang_m;
          const double braking = speed_mps_ * speed_mps_ / (2 * 0.5) + 0.005;
          cross_yellow = (speed_mps_ > 0.01 && shown->min_end_s &&
                          to_clear / speed_mps_ < *shown->min_end_s) ||
                         (speed_mps_ > 0.01 && to_line < braking);
        }
        stop = !as_stop_sign && !go && !cross_yellow && to_line > 0;
        if (stop) {
          decision.reason = DriverDecision::Reason::kRedLight;
        } else if (to_line > 0 && !BoxClear(x, X_MV, lidar)) {
          // Not over the line yet: a vehicle in the box has the right of way.
          stop = true;
          decision.reason = DriverDecision::Reason::kGiveWay;
        }
      }
    } else if (x.control == maps::Control::kStop && !options_.ignore_stop_signs) {
      stop = StopSign(line_s, x, to_line, X_MV, lidar, now);
      if (stop) decision.reason = DriverDecision::Reason::kStopSign;
    }
    if (stop) {
      // Down to a creep (not below it: the last centimetres at a throttle the command noise
      // swamps stop and start the car again and again), then held at the line.
      const double room = to_line - options_.stop_gap_m;
      throttle =
          std::min(throttle, std::clamp(options_.cruise_throttle * room / options_.slow_down_m,
                                        options_.creep_fraction * options_.cruise_throttle,
                                        options_.cruise_throttle));
      if (room < 0.01) throttle = 0.0;
    }
    break;  // only the next stop line matters
  }
  // An advisory speed: never faster than asked (its throttle, corrected by the speed error).
  if (speed_limit_mps) {
    const double capped = std::clamp(
        (*speed_limit_mps + (*speed_limit_mps - speed_mps_)) / options_.top_speed_mps, 0.0, 1.0);
    if (capped < throttle) {
      throttle = capped;
      decision.reason = DriverDecision::Reason::kAdvisory;
    }
  }
  // Something on its path close ahead (a car, a box): slow down, then stop. Only what is on
  // its own path counts: in an intersection's box, vehicles waiting at the other stop lines
  // are close, and often straight ahead, but not in its way.
  if (!lidar.empty() && !options_.ignore_obstacles) {
    const double gap = GapAhead(X_MV, lidar, front_s, 2 * options_.obstacle_stop_m);
    if (std::isfinite(gap)) {
      const double scale =
          std::clamp((gap - options_.obstacle_stop_m) / options_.obstacle_stop_m, 0.0, 1.0);
      if (options_.cruise_throttle * scale < throttle) {
        throttle = options_.cruise_throttle * scale;
        decision.reason = DriverDecision::Reason::kObstacle;
      }
    }
  }
  // At the end of its route: stop with the front at the end of the last lane.
  if (AtRouteEnd()) {
    const Piece& last = route_.back();
    const double room = last.start_s + PieceLength(last) - front_s - options_.stop_gap_m;
    const double scale = std::clamp(room / options_.slow_down_m, 0.0, 1.0);
    if (options_.cruise_throttle * scale < throttle) {
      throttle = room < 0.01 ? 0.0 : options_.cruise_throttle * scale;
      decision.reason = DriverDecision::Reason::kGoal;
    }
  }
  decision.throttle = throttle;
  return decision;
}

std::optional<StopLineAhead> LaneDriver::NextStopLine() const { return next_line_; }

bool LaneDriver::InIntersection(IntersectionId x) const {
  const double rear = progress_s_ - options_.rear_overhang_m;
  const double front = progress_s_ + options_.front_overhang_m;
  for (const Piece& piece : route_) {
    if (piece.movement == nullptr || piece.movement->intersection != x) continue;
    if (piece.start_s < front && piece.start_s + PieceLength(piece) > rear) return true;
  }
  return false;
}

std::string LaneDriver::lane_name() const {
  for (const Piece& piece : route_) {
    if (piece.lane != nullptr && piece.start_s + PieceLength(piece) >= progress_s_) {
      return piece.lane->name;
    }
  }
  return {};
}

}  // namespace autodrive::vehicle_sim
