#include "traffic/cosim.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <unordered_set>

#include "common/cpu_time.h"
#include "common/error.h"
#include "scm/core/city.h"

namespace autodrive::traffic {

namespace {

// A movement of no traffic light (link_of_movement_).
constexpr std::size_t kNoLight = std::numeric_limits<std::size_t>::max();

// Edges a circulating vehicle's route holds ahead of it after an extension.
constexpr std::size_t kWalkEdges = 16;
// A route is extended when it has this many edges left.
constexpr std::size_t kExtendAt = 4;

std::uint8_t ObjectClass(const std::string& vclass) {
  if (vclass == "bus" || vclass == "coach") return 2;
  if (vclass == "truck" || vclass == "trailer" || vclass == "delivery") return 3;
  if (vclass == "motorcycle" || vclass == "moped") return 4;
  if (vclass == "bicycle") return 5;
  if (vclass == "pedestrian") return 6;
  if (vclass == "emergency") return 7;
  return 1;
}

// SUMO's signal bits (0 right blinker, 1 left blinker, 3 brake light) as TrafficObject's (0
// left, 1 right, 2 brake).
std::uint8_t Signals(int sumo) {
  std::uint8_t out = 0;
  if ((sumo & 2) != 0) out |= 1U;
  if ((sumo & 1) != 0) out |= 2U;
  if ((sumo & 8) != 0) out |= 4U;
  return out;
}

std::string Seconds(double s) { return fmt::format("{:.6f}", s); }

}  // namespace

double YawFromSumoAngle(double angle_deg) {
  return std::remainder(std::numbers::pi / 2 - angle_deg * std::numbers::pi / 180,
                        2 * std::numbers::pi);
}

double SumoAngleFromYaw(double yaw_rad) {
  const double a = 90.0 - yaw_rad * 180 / std::numbers::pi;
  return a - 360.0 * std::floor(a / 360.0);
}

CoSimulation::CoSimulation(const scm::City& city, const TrafficConfig& config, Options options)
    : city_(city),
      config_(config),
      lights_(city),
      rng_(config.seed),
      step_s_(ToSeconds(config.step_s)),
      expected_lab_cars_(options.expected_lab_cars),
      lab_car_wait_s_(ToSeconds(options.lab_car_wait)) {
  std::filesystem::create_directories(options.work_dir);
  network_ =
      std::make_unique<TrafficNetwork>(city.map, options.work_dir / "network", config.speed_mps);
  index_ = std::make_unique<maps::MapIndex>(city.map);
  heads_.resize(city.map.signal_heads.size() + 1);
  for (const TypeShare& t : config_.mix) {
    AUTODRIVE_THROW_UNLESS(!t.type.empty(), "traffic.mix: a type without a name");
  }
  for (const FlowConfig& f : config_.flows) {
    Flow flow{f, network_->EdgeOfLane(f.from), "", 0};
    if (!f.to.empty()) {
      flow.to_edge = network_->EdgeOfLane(f.to);
      AUTODRIVE_THROW_UNLESS(!network_->Route(flow.from_edge, flow.to_edge).empty(),
                             "traffic.flows: no route from " << f.from << " to " << f.to);
    }
    flows_.push_back(std::move(flow));
  }
  StartSumo(options);
  network_->LearnInternalLanes(*api_);
  light_states_.resize(lights_.lights().size());
  IndexStopLanes();
  LabCarClaims::Options claims;
  claims.length_m = TypeSize(network_->files().vehicle_type).length / network_->scale();
  claims.body_centre_ahead_m = config_.lab_cars.body_centre_ahead_m;
  claims_ = std::make_unique<LabCarClaims>(city.map, *index_, claims);
  // Before any report every light is dark: all-way stops.
  UpdateLights(MonoTime{});
  for (const TypeShare& t : config_.mix) (void)TypeSize(t.type);  // an unknown type throws here
}

CoSimulation::~CoSimulation() {
  try {
    api_->Close();
  } catch (const std::exception& e) {
    spdlog::warn("traffic: closing SUMO: {}", e.what());
  }
}

void CoSimulation::StartSumo(Options& options) {
  const maps::SumoExport& files = network_->files();
  std::vector<std::string> args = {config_.sumo.binary,
                                   "-c",
                                   files.config_file.string(),
                                   "--step-length",
                                   Seconds(step_s_),
                                   "--seed",
                                   std::to_string(config_.seed % 2147483647),
                                   "--no-step-log",
                                   "true",
                                   "--time-to-teleport",
                                   "-1",
                                   "--collision.check-junctions",
                                   options.check_junction_collisions ? "true" : "false",
                                   "--collision.action",
                                   "warn",
                                   "--log",
                                   (options.work_dir / "sumo.log").string()};
  if (!config_.route_files.empty()) {
    std::string joined;
    for (const std::string& f : config_.route_files) joined += (joined.empty() ? "" : ",") + f;
    args.insert(args.end(), {"--route-files", joined});
  }
  args.insert(args.end(), config_.sumo.args.begin(), config_.sumo.args.end());
  api_ = std::move(options.api);
  if (!api_) api_ = config_.sumo.traci_port != 0 ? MakeTraciApi() : MakeLibsumoApi();
  api_->Start(args, config_.sumo.traci_port, config_.sumo.clients);
}

const SumoTypeSize& CoSimulation::TypeSize(const std::string& type) {
  auto it = type_sizes_.find(type);
  if (it == type_sizes_.end()) it = type_sizes_.emplace(type, api_->TypeSize(type)).first;
  return it->second;
}

const std::string& CoSimulation::PickType() {
  double total = 0;
  for (const TypeShare& t : config_.mix) total += t.weight;
  if (total <= 0) return config_.mix.front().type;
  double r = std::uniform_real_distribution<double>(0.0, total)(rng_);
  for (const TypeShare& t : config_.mix) {
    if (r < t.weight) return t.type;
    r -= t.weight;
  }
  return config_.mix.back().type;
}

void CoSimulation::AddVehicle(const std::string& id, const std::string& type,
                              std::vector<std::string> route, bool circulating,
                              const std::string& depart_pos) {
  const std::string route_id = "r_" + id;
  api_->AddRoute(route_id, route);
  api_->AddVehicle(id, route_id, type, "now", "best", depart_pos, "0");
  if (circulating) circulating_[id].route_length = route.size();
}

void CoSimulation::InsertRandomVehicles() {
  const double gap = network_->scale() * 0.05;
  // Clear of the lab's cars, in SUMO since the first step.
  std::vector<std::tuple<std::string, double, double>> lab;
  for (const SumoVehicleState& v : states_) {
    if (lab_ids_.count(v.id) == 0 || v.lane.empty() || v.lane.front() == ':') continue;
    const double length = TypeSize(v.type).length;
    lab.emplace_back(v.lane.substr(0, v.lane.rfind('_')), v.lane_pos - length - gap,
                     v.lane_pos + gap);
  }
  const std::vector<Placement> placed = network_->PlaceVehicles(
      config_.vehicles, kWalkEdges, gap, rng_,
      [this]() -> const std::string& { return PickType(); },
      [this](const std::string& type) { return TypeSize(type).length; }, lab);
  if (placed.size() < static_cast<std::size_t>(config_.vehicles)) {
    spdlog::warn("traffic: room for {} of the {} vehicles only", placed.size(), config_.vehicles);
  }
  for (const Placement& p : placed) {
    AddVehicle("bg_" + std::to_string(next_id_++), p.type, p.route, true,
               fmt::format("{:.3f}", p.pos));
  }
}

void CoSimulation::ReportLamp(SignalHeadId head, int lamp, MonoTime now) {
  if (head.value() >= heads_.size()) return;
  HeadReading& reading = heads_[head.value()];
  if (!reading.Report(lamp, now)) return;
  // The lights it shows are read again at the next step, and, where a flash may be starting or
  // ending, until a flash window after the change.
  for (const std::size_t light : lights_of_head_[head.value()]) {
    relight_[light] = true;
    if (reading.MayFlash()) {
      recheck_until_[light] =
          std::max(recheck_until_[light], now + config_.lights.flash_window_s + config_.step_s);
    }
  }
}

void CoSimulation::UpdateLights(MonoTime now) {
  for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
    // Only where a lamp changed lately, or an all-way stop is being run.
    if (!all_way_[i] && !relight_[i] && now > recheck_until_[i] && !light_states_[i].empty()) {
      continue;
    }
    relight_[i] = false;
    aspect_states_[i] = lights_.State(i, heads_, now, config_.lights.flash_window_s);
    const bool now_all_way = aspect_states_[i].find('s') != std::string::npos;
    if (now_all_way != all_way_[i]) {
      all_way_[i] = now_all_way;
      if (now_all_way) {
        ++all_way_count_;
      } else {
        --all_way_count_;
      }
    }
    // All-way stop links: red, but green for the vehicles granted (ArbitrateAllWayStops).
    std::string state = aspect_states_[i];
    for (char& c : state) {
      if (c == 's') c = 'r';
    }
    for (const Grant& g : grants_[i]) {
      if (aspect_states_[i][g.link] == 's') state[g.link] = 'G';
    }
    for (std::size_t k = 0; k < state.size(); ++k) {
      if (held_[i][k]) state[k] = 'r';
    }
    if (state == light_states_[i]) continue;
    api_->SetLightState(lights_.lights()[i].tls, state);
    light_states_[i] = std::move(state);
  }
}

void CoSimulation::HoldForLabCars() {
  // Every lab car in SUMO, where it was last heard of (the Eye or the fleet may skip a step).
  std::vector<LabCarPose>& cars = held_for_;
  cars.clear();
  for (const auto& [name, lab] : lab_cars_) {
    if (lab.in_sumo) cars.push_back(lab.pose);
  }
  if (cars.empty() && held_lights_.empty()) return;
  std::sort(cars.begin(), cars.end(),
            [](const LabCarPose& a, const LabCarPose& b) { return a.name < b.name; });
  claims_->Update(cars, [&](MovementId m) {
    if (m.value() >= link_of_movement_.size()) return false;
    const auto [light, link] = link_of_movement_[m.value()];
    if (light == kNoLight) return false;
    const std::string& aspect = aspect_states_[light];
    return aspect.empty() || aspect[link] != 'r';
  });
  std::vector<std::vector<bool>> before;
  for (const std::size_t i : held_lights_) {
    before.push_back(held_[i]);
    std::fill(held_[i].begin(), held_[i].end(), false);
  }
  std::vector<std::size_t> lights;
  for (const MovementId m : claims_->held()) {
    if (m.value() >= link_of_movement_.size()) continue;
    const auto [light, link] = link_of_movement_[m.value()];
    if (light == kNoLight) continue;
    held_[light][link] = true;
    if (std::find(lights.begin(), lights.end(), light) == lights.end()) lights.push_back(light);
  }
  // A light whose held links changed is set again at once.
  for (std::size_t j = 0; j < held_lights_.size(); ++j) {
    if (held_[held_lights_[j]] != before[j]) relight_[held_lights_[j]] = true;
  }
  for (const std::size_t i : lights) {
    if (std::find(held_lights_.begin(), held_lights_.end(), i) == held_lights_.end()) {
      relight_[i] = true;
    }
  }
  held_lights_ = std::move(lights);
}

void CoSimulation::PlaceLabCars(const std::vector<LabCarPose>& cars, MonoTime now) {
  for (const LabCarPose& car : cars) {
    LabCar& lab = lab_cars_[car.name];
    lab.last_seen = now;
    lab.pose = car;
    const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
    const Eigen::Vector2d centre = car.position + heading * config_.lab_cars.body_centre_ahead_m;
    const auto match = index_->NearestLane(centre, config_.lab_cars.max_lane_distance_m);
    // Inside an intersection's box a car is far from every lane's centreline (its paths there
    // are movements, not lanes): one in SUMO stays, moved where it is, as long as it is on the
    // road (out of SUMO, SUMO's cars would drive through it in the box).
    const bool on_road = match || (lab.in_sumo && index_->IsDrivable(centre));
    if (!on_road) {
      if (lab.in_sumo) {
        api_->Remove(lab.sumo_id);
        lab.in_sumo = false;
        spdlog::info("traffic: {} is off the road: removed from SUMO until it is back", car.name);
      }
      continue;
    }
    if (!lab.in_sumo) {
      lab.sumo_id = car.name + (lab.entries == 0 ? "" : "#" + std::to_string(lab.entries));
      ++lab.entries;
      lab_ids_.insert(lab.sumo_id);
      const std::string& edge = network_->EdgeOfLane(city_.map.lane(match->lane).name);
      const std::string route_id = "r_" + lab.sumo_id;
      api_->AddRoute(route_id, {edge});
      api_->AddVehicle(lab.sumo_id, route_id, network_->files().vehicle_type, "now", "best", "base",
                       "0");
      api_->SetSpeedMode(lab.sumo_id, 0);
      lab.in_sumo = true;
      lab.route_via.reset();
      lab.kept_route = false;
    }
  }
  // Cars not heard from for too long leave SUMO.
  for (auto& [name, lab] : lab_cars_) {
    if (lab.in_sumo && now - lab.last_seen > config_.lab_cars.staleness_s) {
      api_->Remove(lab.sumo_id);
      lab.in_sumo = false;
      spdlog::info("traffic: {} is stale: removed from SUMO until it is heard again", name);
    }
  }
  stats_.lab_cars_placed = std::count_if(lab_cars_.begin(), lab_cars_.end(),
                                         [](const auto& kv) { return kv.second.in_sumo; });
}

void CoSimulation::MoveLabCars() {
  const double s = network_->scale();
  const SumoTypeSize& nigel = TypeSize(network_->files().vehicle_type);
  // Every lab car in SUMO, also one not heard from this step: where it was last heard of (left
  // to itself, SUMO would drive it on along its route, and remove it at the route's end).
  for (const LabCarPose& car : held_for_) {
    LabCar& lab = lab_cars_.at(car.name);
    const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
    // SUMO's position is the front bumper's middle.
    const Eigen::Vector2d front =
        car.position + heading * (config_.lab_cars.body_centre_ahead_m + nigel.length / s / 2);
    Eigen::Vector2d at = front;  // where SUMO is to have its front
    bool keep_route = false;
    // The lane it should be on (a hint only: SUMO takes the lane nearest the point).
    std::string hint_edge;
    int hint_lane = -1;
    const auto hint = [&](const std::string& sumo_lane) {
      const auto k = sumo_lane.rfind('_');
      hint_edge = sumo_lane.substr(0, k);
      hint_lane = std::stoi(sumo_lane.substr(k + 1));
    };
    if (const auto under = claims_->Under(car.name)) {
      // In a box, on a movement's path. The lane nearest its front may be another movement's
      // (paths cross there, or pass side by side): SUMO is to keep it on this one's lanes.
      const MovementId m = under->first;
      if (lab.route_via != m && (lab.lane.empty() || lab.lane.front() != ':')) {
        // Its route through the movement: SUMO takes it while the car is on the lane in (not
        // on another movement's internal lane, "leading elsewhere").
        const maps::SumoMovement& sm = network_->files().movement(m);
        try {
          api_->SetRoute(lab.sumo_id, {sm.from.edge, sm.to.edge});
          lab.route_via = m;
        } catch (const SumoError& e) {
          spdlog::debug("traffic: {:.2f} s: {} keeps its route in SUMO: {}", time_s_, car.name,
                        e.what());
        }
      }
      if (lab.route_via == m) {
        keep_route = true;  // SUMO's route runs through it: at its pose, on the route's lanes
      } else {
        // SUMO has it on another movement's internal lane: its front on this one's path (or,
        // past the box, on its lane out), where the nearest lane is the movement's own. SUMO
        // takes it, and the route through it.
        const maps::Movement& mv = city_.map.movement(m);
        const PolylinePoint q = NearestOnPolyline(mv.path, front);
        if (q.along_m < q.length_m) {
          at = q.point;
          const std::vector<std::string>& internal = network_->InternalLanes(m);
          if (!internal.empty()) {
            const auto k = std::min(internal.size() - 1,
                                    static_cast<std::size_t>(q.along_m / q.length_m *
                                                             static_cast<double>(internal.size())));
            hint(internal[k]);
          }
        } else {
          at = NearestOnPolyline(city_.map.lane(mv.to).centreline, front).point;
          hint(network_->files().movement(m).to.id());
        }
      }
    } else if (const auto on = FrontOnItsLane(car, front)) {
      // On a lane: its front on that lane's SUMO lane (or the next's, once past its end). SUMO
      // takes a move's lane when the point is beside that lane; else it weighs the lanes near
      // the point, and at a tile's join (where lanes end) that weighing has put a car on the
      // lane beside it that runs the other way.
      at = on->first;
      hint(on->second);
    } else if (const auto match = index_->NearestLane(
                   car.position + heading * config_.lab_cars.body_centre_ahead_m,
                   config_.lab_cars.max_lane_distance_m)) {
      hint_edge = network_->EdgeOfLane(city_.map.lane(match->lane).name);
      hint_lane = 0;
    }
    try {
      api_->MoveToXY(lab.sumo_id, hint_edge, hint_lane, at.x() * s, at.y() * s,
                     SumoAngleFromYaw(car.yaw_rad), keep_route);
      lab.kept_route = keep_route;
    } catch (const SumoError& e) {
      ++stats_.lab_car_misses;
      spdlog::warn("traffic: {} could not be placed in SUMO: {}", car.name, e.what());
    }
  }
}

std::optional<std::pair<Eigen::Vector2d, std::string>> CoSimulation::FrontOnItsLane(
    const LabCarPose& car, const Eigen::Vector2d& front) {
  // Its lane: the nearest to its body's centre that runs its way (the lane beside it runs the
  // other way, and may be nearer where it cuts a curve).
  const Eigen::Vector2d heading(std::cos(car.yaw_rad), std::sin(car.yaw_rad));
  const auto on = index_->NearestLaneHeading(
      car.position + heading * config_.lab_cars.body_centre_ahead_m, car.yaw_rad,
      config_.lab_cars.max_lane_distance_m, LabCarClaims::kAlignedRad);
  if (!on) return std::nullopt;
  const maps::Lane* lane = &city_.map.lane(on->lane);
  PolylinePoint q = NearestOnPolyline(lane->centreline, front);
  // SUMO's lanes end where the map's do (a join between tiles is a junction of no size): a
  // front at or past its lane's end is on the next one.
  constexpr double kInside = 0.002;  // metres from a lane's ends (SUMO: 2.8 cm)
  if (q.along_m > q.length_m - kInside) {
    if (lane->successors.size() != 1) return std::nullopt;  // into an intersection
    lane = &city_.map.lane(lane->successors.front());
    q = NearestOnPolyline(lane->centreline, front);
  }
  // The point beside the lane, within its width: where SUMO's weighing never decides.
  const double along = std::clamp(q.along_m, kInside, std::max(kInside, q.length_m - kInside));
  const auto [p, direction] = PointAlong(lane->centreline, along);
  const Eigen::Vector2d left(-std::sin(direction), std::cos(direction));
  const double half = std::max(0.0, lane->width_m / 2 - 0.01);
  const Eigen::Vector2d at = p + left * std::clamp((front - q.point).dot(left), -half, half);
  // The SUMO lane of the map lane there (a turning loop runs along two).
  const std::vector<maps::SumoLaneRef>& pieces = network_->files().lane_pieces.at(lane->id);
  std::size_t k = 0;
  double start = 0;
  const double s = network_->scale();
  while (k + 1 < pieces.size() && along > start + LaneLength(pieces[k].id()) / s) {
    start += LaneLength(pieces[k].id()) / s;
    ++k;
  }
  return std::pair{at, pieces[k].id()};
}

std::string CoSimulation::DescribeLabCars(const std::string& a, const std::string& b) const {
  std::string out;
  for (const auto& [name, lab] : lab_cars_) {
    if (lab.sumo_id != a && lab.sumo_id != b) continue;
    out +=
        fmt::format("; {} was at ({:.3f}, {:.3f}) heading {:.2f} rad, on {} in SUMO before", name,
                    lab.pose.position.x(), lab.pose.position.y(), lab.pose.yaw_rad, lab.lane);
    if (claims_->InBox(name)) out += fmt::format(", in a box");
  }
  return out;
}

void CoSimulation::NoteLabLane(const SumoVehicleState& v) {
  for (auto& [name, lab] : lab_cars_) {
    if (lab.sumo_id != v.id) continue;
    // On a movement's internal lane, SUMO's route for it runs through that movement (a move
    // that may leave its route, and SUMO put it there, makes its route the movement's lanes in
    // and out). Anywhere else, after such a move, its route is whatever SUMO made it.
    if (const auto m = movement_of_lane_.find(v.lane); m != movement_of_lane_.end()) {
      lab.route_via = m->second;
    } else if (!lab.kept_route) {
      lab.route_via.reset();
    }
    if (lab.lane != v.lane) {
      spdlog::debug("traffic: {:.2f} s: {} is on {} in SUMO", time_s_, name, v.lane);
      lab.lane = v.lane;
    }
    return;
  }
}

void CoSimulation::DepartFlows() {
  for (std::size_t i = 0; i < flows_.size(); ++i) {
    Flow& f = flows_[i];
    const double period = 3600.0 / f.config.per_hour;
    while ((f.config.count == 0 || f.sent < f.config.count) &&
           ToSeconds(f.config.begin_s) + f.sent * period <= time_s_ + 1e-9) {
      const bool circulating = f.to_edge.empty();
      std::vector<std::string> route = circulating ? std::vector<std::string>{f.from_edge}
                                                   : network_->Route(f.from_edge, f.to_edge);
      if (circulating) {
        for (std::string& e : network_->RandomWalk(f.from_edge, kWalkEdges, rng_))
          route.push_back(std::move(e));
      }
      AddVehicle("flow" + std::to_string(i) + "_" + std::to_string(f.sent), f.config.type,
                 std::move(route), circulating, "base");
      ++f.sent;
    }
  }
}

void CoSimulation::ExtendRoutes() {
  // Routes hold four edges ahead at least when extended: checking twice a second is enough.
  if (stats_.steps % 10 != 0) return;
  for (SumoVehicleState& v : states_) {
    const auto it = circulating_.find(v.id);
    if (it == circulating_.end()) continue;
    // Inside a junction SUMO's route index still names the edge before it: extend once the
    // vehicle is on an edge again.
    if (!v.lane.empty() && v.lane.front() == ':') continue;
    v.route_index = api_->RouteIndex(v.id);
    std::size_t& length = it->second.route_length;
    const auto index = static_cast<std::size_t>(std::max(0, v.route_index));
    if (length > index + kExtendAt) continue;
    // SUMO's own route (it is the truth; a replacement restarts its index).
    const std::vector<std::string> route = api_->Route(v.id);
    if (index >= route.size()) continue;
    std::vector<std::string> ahead(route.begin() + static_cast<std::ptrdiff_t>(index), route.end());
    const std::size_t before = ahead.size();
    for (std::string& e : network_->RandomWalk(ahead.back(), kWalkEdges, rng_)) {
      ahead.push_back(std::move(e));
    }
    if (ahead.size() == before) continue;  // a road out of the map: it will arrive there
    api_->SetRoute(v.id, ahead);
    length = ahead.size();
    ++stats_.route_extensions;
  }
}

// A circulating car has no destination: one that waits at the head of its lane for a road
// that is full, while another road from the intersection has room, turns there instead, as a
// driver would. Without it the random walks of a small closed town run into gridlock: rings of
// full lanes whose first cars each wait for the next full lane of the ring.
void CoSimulation::RerouteBlocked() {
  constexpr double kWait_s = 3.0;  // standing this long at the head of its lane
  // Once a second: a wait of seconds needs no finer look, and the look costs a lookup by name
  // per vehicle.
  if (stats_.steps % 20 != 0) return;
  const double s = network_->scale();
  const double gap = network_->files().scale * 0.05;
  // Circulating vehicles standing on a lane into an intersection, and since when.
  std::unordered_map<std::string, double> blocked;
  std::vector<const SumoVehicleState*> waited;  // long enough
  for (const SumoVehicleState& v : states_) {
    if (v.speed_mps > 0.01 * s || stop_lanes_.count(v.lane) == 0 || circulating_.count(v.id) == 0) {
      continue;
    }
    const double since = blocked_since_.try_emplace(v.id, time_s_).first->second;
    blocked.emplace(v.id, since);
    if (time_s_ - since >= kWait_s - 1e-9) waited.push_back(&v);
  }
  blocked_since_ = std::move(blocked);
  if (waited.empty()) return;
  // What the vehicles take of each lane: those on it, and those in a junction on their way in.
  std::unordered_map<std::string, double> taken;
  for (const SumoVehicleState& v : states_) {
    const double length = TypeSize(v.type).length + gap;
    if (const auto link = link_of_lane_.find(v.lane); link != link_of_lane_.end()) {
      taken[exit_of_link_[link->second.first][link->second.second]] += length;
    } else {
      taken[v.lane] += length;
    }
  }
  const auto room = [&](const std::string& lane) {
    const auto it = taken.find(lane);
    return LaneLength(lane) - (it == taken.end() ? 0.0 : it->second);
  };
  for (const SumoVehicleState* v : waited) {
    const StopLane& lane = stop_lanes_.at(v->lane);
    const auto& grants = grants_[lane.light];
    if (std::any_of(grants.begin(), grants.end(),
                    [&](const Grant& g) { return g.vehicle == v->id; })) {
      continue;
    }
    const double length = TypeSize(v->type).length + gap;
    // Only a lane with a full exit can hold a vehicle up (most stand at a red light): its
    // route, a call each, is read only then.
    if (std::all_of(lane.links.begin(), lane.links.end(),
                    [&](const StopLane::Link& l) { return room(l.lane) >= length; })) {
      continue;
    }
    const double waited_s = time_s_ - blocked_since_.at(v->id);
    if (api_->LanePosition(v->id) < lane.length - 0.1 * s) continue;  // not the first
    const std::vector<std::string> route = api_->Route(v->id);
    const int index = api_->RouteIndex(v->id);
    const auto next = static_cast<std::size_t>(index) + 1;
    if (index < 0 || next >= route.size()) continue;
    const auto current = std::find_if(lane.links.begin(), lane.links.end(),
                                      [&](const auto& l) { return l.edge == route[next]; });
    if (current == lane.links.end() || room(current->lane) >= length) continue;
    std::vector<const StopLane::Link*> open;
    for (const StopLane::Link& l : lane.links) {
      if (&l != &*current && network_->Circulates(l.edge) && room(l.lane) >= length) {
        open.push_back(&l);
      }
    }
    if (open.empty()) continue;
    const StopLane::Link& to =
        *open[std::uniform_int_distribution<std::size_t>(0, open.size() - 1)(rng_)];
    std::vector<std::string> ahead{route[static_cast<std::size_t>(index)], to.edge};
    for (std::string& e : network_->RandomWalk(to.edge, kWalkEdges, rng_)) {
      ahead.push_back(std::move(e));
    }
    api_->SetRoute(v->id, ahead);
    circulating_[v->id].route_length = ahead.size();
    taken[to.lane] += length;
    blocked_since_.erase(v->id);
    ++stats_.reroutes;
    spdlog::debug("traffic: {} waited {:.0f} s for {} (full): turns to {} instead", v->id, waited_s,
                  current->edge, to.edge);
  }
}

void CoSimulation::IndexStopLanes() {
  link_of_movement_.assign(city_.map.movements.size() + 1, {kNoLight, 0});
  std::unordered_map<std::string, std::size_t> light_of;
  for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
    light_of.emplace(lights_.lights()[i].tls, i);
  }
  for (const maps::Intersection& x : city_.map.intersections) {
    if (x.control != maps::Control::kSignal && x.control != maps::Control::kStop) continue;
    for (const MovementId mid : x.movements) {
      const maps::SumoMovement& sm = network_->files().movement(mid);
      const std::size_t light = light_of.at(sm.junction);
      const auto link = static_cast<std::size_t>(sm.tls_link_index.value_or(0));
      link_of_movement_[mid.value()] = {light, link};
      StopLane& lane = stop_lanes_[sm.from.id()];
      lane.light = light;
      lane.links.push_back(StopLane::Link{sm.to.edge, sm.to.id(), link});
      exit_of_link_.resize(std::max(exit_of_link_.size(), light + 1));
      auto& exits = exit_of_link_[light];
      exits.resize(std::max(exits.size(), link + 1));
      exits[link] = sm.to.id();
      auto& lights = exit_lights_[sm.to.id()];
      if (std::find(lights.begin(), lights.end(), light) == lights.end()) lights.push_back(light);
      for (const std::string& internal : network_->InternalLanes(mid)) {
        link_of_lane_.emplace(internal, std::pair{light, link});
        movement_of_lane_.emplace(internal, mid);
      }
    }
  }
  for (auto& [id, lane] : stop_lanes_) lane.length = LaneLength(id);
  aspect_states_.resize(lights_.lights().size());
  all_way_.assign(lights_.lights().size(), false);
  occupied_.resize(lights_.lights().size());
  held_.resize(lights_.lights().size());
  for (std::size_t i = 0; i < occupied_.size(); ++i) {
    occupied_[i].assign(lights_.lights()[i].heads.size(), false);
    held_[i].assign(lights_.lights()[i].heads.size(), false);
  }
  grants_.resize(lights_.lights().size());
  recheck_until_.assign(lights_.lights().size(), MonoTime{});
  relight_.assign(lights_.lights().size(), false);
  lights_of_head_.resize(heads_.size());
  for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
    for (const auto& link : lights_.lights()[i].heads) {
      for (const SignalHeadId h : link) {
        auto& of = lights_of_head_.at(h.value());
        if (std::find(of.begin(), of.end(), i) == of.end()) of.push_back(i);
      }
    }
  }
}

double CoSimulation::LaneLength(const std::string& sumo_lane) {
  auto it = lane_lengths_.find(sumo_lane);
  if (it == lane_lengths_.end())
    it = lane_lengths_.emplace(sumo_lane, api_->LaneLength(sumo_lane)).first;
  return it->second;
}

const CoSimulation::LaneInfo& CoSimulation::InfoOf(const std::string& sumo_lane) {
  auto it = lane_info_.find(sumo_lane);
  if (it != lane_info_.end()) return it->second;
  LaneInfo info;
  info.map_name = &network_->MapName(sumo_lane);
  const auto add = [&](std::size_t light) {
    if (std::find(info.lights.begin(), info.lights.end(), light) == info.lights.end()) {
      info.lights.push_back(light);
    }
  };
  if (const auto stop = stop_lanes_.find(sumo_lane); stop != stop_lanes_.end()) {
    add(stop->second.light);
  }
  if (const auto link = link_of_lane_.find(sumo_lane); link != link_of_lane_.end()) {
    add(link->second.first);
  }
  if (const auto exit = exit_lights_.find(sumo_lane); exit != exit_lights_.end()) {
    for (const std::size_t light : exit->second) add(light);
  }
  return lane_info_.emplace(sumo_lane, std::move(info)).first->second;
}

bool CoSimulation::AllWayNear(const LaneInfo& info) const {
  return all_way_count_ != 0 && std::any_of(info.lights.begin(), info.lights.end(),
                                            [&](std::size_t l) { return all_way_[l]; });
}

// SUMO's own all-way stop (`s` links, or an allway_stop junction) lets a left turn with a
// waiting point inside the junction roll through without stopping, and lets vehicles on
// crossing paths of these small junctions (a 1:14 box at 14x) into the box together. So a
// flashing or dark light is arbitrated here, as drivers do at an all-way stop: every vehicle
// stops at the line (its link is red until then); the one that has stood longest (at least
// half a second) goes, with any others whose movements conflict with no movement granted or
// occupied; its link turns green until it is in the junction, then red again.
void CoSimulation::ArbitrateAllWayStops() {
  constexpr double kStand_s = 0.5;
  constexpr double kGrant_s = 5.0;
  const double s = network_->scale();
  for (std::size_t i = 0; i < lights_.lights().size(); ++i) {
    if (!all_way_[i]) grants_[i].clear();
  }
  if (all_way_count_ == 0) {  // no light runs an all-way stop: nothing to arbitrate
    standing_since_.clear();
    return;
  }
  // Occupied links (a vehicle on their internal lanes) and vehicles standing at a line, of the
  // lights that run an all-way stop (only theirs are read).
  std::vector<std::vector<bool>>& occupied = occupied_;
  for (std::size_t i = 0; i < occupied.size(); ++i) {
    if (all_way_[i]) std::fill(occupied[i].begin(), occupied[i].end(), false);
  }
  struct Waiting {
    double since;
    std::string vehicle;
    const StopLane* lane;
    int route_index;
    std::string type;
  };
  std::vector<Waiting> waiting;
  std::unordered_map<std::string, std::string> lane_of;
  // Room at the start of each lane (SUMO metres up to the last vehicle's back), less what the
  // vehicles in a box or let through on their way into it take.
  std::unordered_map<std::string, double> room;
  const auto take_room = [&](const std::string& lane, double length) {
    auto it = room.find(lane);
    if (it == room.end()) it = room.emplace(lane, LaneLength(lane)).first;
    it->second -= length;
  };
  const double gap = network_->files().scale * 0.05;  // the vehicle types' min gap
  for (const SumoVehicleState& v : states_) {
    // Only the vehicles about the all-way stops running now (and the lab's cars) matter.
    const bool lab = !lab_ids_.empty() && lab_ids_.count(v.id) != 0;
    if (!lab && !AllWayNear(InfoOf(v.lane))) {
      standing_since_.erase(v.id);
      continue;
    }
    lane_of.emplace(v.id, v.lane);
    const double length = TypeSize(v.type).length;
    if (const auto it = link_of_lane_.find(v.lane); it != link_of_lane_.end()) {
      occupied[it->second.first][it->second.second] = true;
      take_room(exit_of_link_[it->second.first][it->second.second], length + gap);
      continue;
    }
    if (!v.lane.empty() && v.lane.front() != ':') {
      auto r = room.find(v.lane);
      if (r == room.end()) r = room.emplace(v.lane, LaneLength(v.lane)).first;
      r->second = std::min(r->second, v.lane_pos - length - gap);
    }
    // A lab car goes whenever its driver decides: what SUMO's vehicles must not start
    // meanwhile is held (HoldForLabCars).
    if (lab) continue;
    const auto lane = stop_lanes_.find(v.lane);
    const bool at_line = lane != stop_lanes_.end() && v.speed_mps < 0.01 * s &&
                         v.lane_pos > lane->second.length - 0.1 * s;
    if (!at_line) {
      standing_since_.erase(v.id);
      continue;
    }
    const auto since = standing_since_.try_emplace(v.id, time_s_).first;
    if (all_way_[lane->second.light]) {
      waiting.push_back(
          Waiting{since->second, v.id, &lane->second, api_->RouteIndex(v.id), v.type});
    }
  }
  // Grants end once the vehicle is in the junction (or gone), or when it did not take its
  // turn within a few seconds (blocked by a vehicle SUMO put in the box: the next one goes).
  std::vector<std::string> lapsed;
  for (std::size_t i = 0; i < grants_.size(); ++i) {
    std::erase_if(grants_[i], [&](const Grant& g) {
      const auto it = lane_of.find(g.vehicle);
      if (it == lane_of.end() || stop_lanes_.count(it->second) == 0) return true;
      // It did not go (SUMO saw no way through): it goes to the back of the queue, and the
      // others may go first (granted again at once, it would hold the intersection for good).
      if (time_s_ - g.since <= kGrant_s) return false;
      lapsed.push_back(g.vehicle);
      ++stats_.all_way_lapsed;
      spdlog::debug("traffic: {} did not take its turn at {} in {:.0f} s", g.vehicle,
                    lights_.lights()[i].tls, kGrant_s);
      return true;
    });
  }
  for (Waiting& w : waiting) {
    if (std::find(lapsed.begin(), lapsed.end(), w.vehicle) == lapsed.end()) continue;
    w.since = time_s_;
    standing_since_[w.vehicle] = time_s_;
  }
  for (std::size_t i = 0; i < grants_.size(); ++i) {
    for (const Grant& g : grants_[i]) take_room(exit_of_link_[i][g.link], g.room);
  }
  std::sort(waiting.begin(), waiting.end(), [](const Waiting& a, const Waiting& b) {
    return a.since != b.since ? a.since < b.since : a.vehicle < b.vehicle;
  });
  for (const Waiting& w : waiting) {
    if (time_s_ - w.since < kStand_s - 1e-9) continue;
    const std::size_t light = w.lane->light;
    auto& grants = grants_[light];
    if (std::any_of(grants.begin(), grants.end(),
                    [&](const Grant& g) { return g.vehicle == w.vehicle; })) {
      continue;
    }
    // Its movement: the link to the next edge of its route.
    const std::vector<std::string> route = api_->Route(w.vehicle);
    const auto next = static_cast<std::size_t>(w.route_index) + 1;
    if (w.route_index < 0 || next >= route.size()) continue;
    const auto link = std::find_if(w.lane->links.begin(), w.lane->links.end(),
                                   [&](const auto& l) { return l.edge == route[next]; });
    if (link == w.lane->links.end()) continue;
    const std::size_t k = link->index;
    if (held_[light][k]) continue;  // a lab car is on its way
    // Only into a lane with room for it: a vehicle waiting in the box for room would hold up
    // every movement it conflicts with (and a grid of all-way stops would lock up).
    const double length = TypeSize(w.type).length;
    take_room(link->lane, 0.0);
    if (room.at(link->lane) < length + gap) continue;
    if (aspect_states_[light][k] != 's') continue;
    const auto& foes = lights_.lights()[light].foes[k];
    const bool clear = std::none_of(foes.begin(), foes.end(), [&](std::size_t f) {
      return occupied[light][f] ||
             std::any_of(grants.begin(), grants.end(), [&](const Grant& g) { return g.link == f; });
    });
    if (!clear) continue;
    grants.push_back(Grant{w.vehicle, k, time_s_, length + gap});
    spdlog::debug("traffic: {:.2f} s: {} may go at {} (link {})", time_s_, w.vehicle,
                  lights_.lights()[light].tls, k);
    room.at(link->lane) -= length + gap;
    ++stats_.all_way_grants;
  }
}

void CoSimulation::ReadVehicles() {
  api_->ReadVehicles(states_);
  const double s = network_->scale();
  std::size_t n = 0;
  read_cache_.resize(std::max(read_cache_.size(), states_.size()));
  for (SumoVehicleState& v : states_) {
    // The output's nth vehicle is mostly the same as the last step's, often on the same lane:
    // its lane's and type's entries are then known without hashing their names.
    // (A lab car leaves the cache alone: it is not in the output.)
    const bool lab = !lab_ids_.empty() && lab_ids_.count(v.id) != 0;
    ReadCache& cache = read_cache_[n];
    const bool same = !lab && n < vehicles_.size() && vehicles_[n].id == v.id;
    if (!lab) {
      cache.lane_changed = !same || cache.info == nullptr || cache.sumo_lane != v.lane;
      if (cache.lane_changed) {
        cache.info = &InfoOf(v.lane);
        cache.sumo_lane = v.lane;
      }
      if (!same || cache.size == nullptr) {
        cache.size = &TypeSize(v.type);
        cache.object_class = ObjectClass(cache.size->vclass);
      }
    }
    const LaneInfo& info = lab ? InfoOf(v.lane) : *cache.info;
    // Lane positions where they matter: the lab's cars, and lanes into, through or out of an
    // all-way stop running now.
    if (lab || AllWayNear(info)) v.lane_pos = api_->LanePosition(v.id);
    if (lab) {
      NoteLabLane(v);
      continue;
    }
    // The output's elements are reused (their strings keep their buffers from step to step).
    if (n == vehicles_.size()) vehicles_.emplace_back();
    TrafficVehicle& out = vehicles_[n++];
    const SumoTypeSize& size = *cache.size;
    if (!same) out.id = v.id;
    out.object_class = cache.object_class;
    out.yaw_rad = YawFromSumoAngle(v.angle_deg);
    const Eigen::Vector2d heading(std::cos(out.yaw_rad), std::sin(out.yaw_rad));
    out.centre = (Eigen::Vector2d(v.x, v.y) - heading * (size.length / 2)) / s;
    out.length_m = size.length / s;
    out.width_m = size.width / s;
    out.height_m = size.height / s;
    out.speed_mps = v.speed_mps / s;
    if (!same || cache.lane_changed) out.map_lane = *info.map_name;
    out.signals = Signals(v.signals);
  }
  vehicles_.resize(n);
}

const std::vector<TrafficVehicle>& CoSimulation::Step(const std::vector<LabCarPose>& lab_cars,
                                                      MonoTime now) {
  PlaceLabCars(lab_cars, now);
  HoldForLabCars();
  MoveLabCars();
  UpdateLights(now);
  // The random vehicles go in once the lab's cars are in the network (placed in the last
  // step), so that none is put where a lab car stands.
  if (!inserted_ && stats_.steps >= 1) {
    // Each expected car in the network as SUMO reported it after the last step.
    const bool all_here =
        std::all_of(expected_lab_cars_.begin(), expected_lab_cars_.end(), [&](const auto& n) {
          const auto it = lab_cars_.find(n);
          return it != lab_cars_.end() && it->second.in_sumo &&
                 std::any_of(states_.begin(), states_.end(),
                             [&](const SumoVehicleState& v) { return v.id == it->second.sumo_id; });
        });
    if (all_here || time_s_ >= lab_car_wait_s_) {
      if (!all_here) {
        spdlog::warn(
            "traffic: not every lab car was heard from in {:.1f} s: the background "
            "vehicles go in now",
            time_s_);
      }
      InsertRandomVehicles();
      inserted_ = true;
    }
  }
  DepartFlows();
  const double cpu0 = ThreadCpuSeconds();
  api_->Step(0.0);
  stats_.sumo_step_cpu_s += ThreadCpuSeconds() - cpu0;
  time_s_ = api_->Time();
  ++stats_.steps;
  const SumoStepEvents events = api_->Events();
  for (const std::string& id : events.departed) {
    if (lab_ids_.count(id) == 0) ++stats_.departed;
  }
  for (const std::string& id : events.arrived) {
    if (lab_ids_.count(id) != 0) {
      // SUMO ends a vehicle's trip at its route's end, a moved one too: in again at the next
      // step (a lab car leaves SUMO only off the road or stale).
      for (auto& [name, lab] : lab_cars_) {
        if (lab.sumo_id != id || !lab.in_sumo) continue;
        lab.in_sumo = false;
        ++stats_.lab_car_misses;
        spdlog::warn("traffic: SUMO ended {}'s trip at {:.2f} s: it goes in again", name, time_s_);
      }
      continue;
    }
    if (circulating_.erase(id) != 0) {
      ++stats_.arrived_unplanned;
      spdlog::error("traffic: circulating vehicle {} left the network at {:.2f} s", id, time_s_);
    } else {
      ++stats_.arrived_planned;
    }
  }
  for (const std::string& id : events.teleported) {
    ++stats_.teleports;
    spdlog::error("traffic: SUMO teleported {} at {:.2f} s", id, time_s_);
  }
  // A collision counts once, when the two start to overlap.
  std::set<std::pair<std::string, std::string>> colliding;
  for (const SumoStepEvents::Collision& c : events.collisions) {
    const auto pair = std::minmax(c.collider, c.victim);
    colliding.emplace(pair.first, pair.second);
    if (colliding_.count({pair.first, pair.second}) != 0) continue;
    if (lab_ids_.count(c.collider) != 0 && lab_ids_.count(c.victim) != 0) {
      // Two lab cars as SUMO places them (on its lanes, from their poses): whether they touch
      // is the simulator's (or the track's) to say, not SUMO's.
      ++stats_.lab_overlaps;
      spdlog::info("traffic: at {:.2f} s two lab cars overlap as placed in SUMO: {}", time_s_,
                   c.description);
      continue;
    }
    ++stats_.collisions;
    spdlog::warn("traffic: collision at {:.2f} s: {}{}", time_s_, c.description,
                 DescribeLabCars(c.collider, c.victim));
  }
  colliding_ = std::move(colliding);
  ReadVehicles();
  ArbitrateAllWayStops();
  ExtendRoutes();
  RerouteBlocked();
  return vehicles_;
}

}  // namespace autodrive::traffic
