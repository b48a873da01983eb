#include "traffic/cosim.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_set>

#include "common/cpu_time.h"
#include "common/error.h"
#include "scm/core/city.h"

namespace autodrive::traffic {

namespace {

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

CoSimulation::CoSimulation(const scm::City& city, const TrafficConfig& config, Options options)
    : city_(city),
      config_(config),
      lights_(city),
      lamps_(lights_, city.map.signal_heads.empty() ? 0 : city.map.signal_heads.back().id.value(),
             config.lights.flash_window_s, config.step_s),
      expected_lab_cars_(options.expected_lab_cars),
      lab_car_wait_(options.lab_car_wait) {
  std::filesystem::create_directories(options.work_dir);
  network_ =
      std::make_unique<TrafficNetwork>(city.map, options.work_dir / "network", config.speed_mps);
  demand_ = std::make_unique<Demand>(config_, *network_);
  StartSumo(options);
  sumo_ = std::make_unique<SumoCache>(*api_);
  network_->LearnInternalLanes(*api_);
  links_ = std::make_unique<LinkIndex>(IndexLinks(
      lights_, *network_, [this](const std::string& lane) { return sumo_->LaneLength(lane); }));
  lanes_ = std::make_unique<LaneLookup>(
      *links_,
      [this](const std::string& lane) -> const std::string& { return network_->MapName(lane); });
  all_way_ = std::make_unique<AllWayStops>(lights_, *links_, network_->scale(),
                                           network_->files().scale * 0.05);
  lab_ = std::make_unique<LabCarPlacement>(*network_, config_.lab_cars,
                                           sumo_->TypeSize(network_->files().vehicle_type).length);
  // Before any report every light is dark: all-way stops.
  SetLights(MonoTime{});
  for (const TypeShare& t : config_.mix) (void)sumo_->TypeSize(t.type);  // an unknown type throws
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
  std::vector<std::string> args = {
      config_.sumo.binary, "-c", files.config_file.string(), "--step-length",
      Seconds(ToSeconds(config_.step_s)), "--seed", std::to_string(config_.seed % 2147483647),
      "--no-step-log", "true", "--time-to-teleport", "-1", "--collision.check-junctions",
      options.check_junction_collisions ? "true" : "false", "--collision.action", "warn",
      // SUMO's cars brake hard behind lab cars, which stop and
      // start as no SUMO driver would: after 5 warnings of a kind
      // SUMO counts the rest instead of printing each.
      "--aggregate-warnings", "5", "--log", (options.work_dir / "sumo.log").string()};
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

void CoSimulation::Add(const std::vector<Departure>& departures) {
  for (const Departure& d : departures) {
    const std::string route_id = "r_" + d.id;
    api_->AddRoute(route_id, d.route);
    api_->AddVehicle(d.id, route_id, d.type, "now", "best", d.depart_pos, "0");
  }
}

void CoSimulation::ReportLamp(SignalHeadId head, int lamp, MonoTime now) {
  lamps_.Report(head, lamp, now);
}

void CoSimulation::SetLights(MonoTime now) {
  for (const std::size_t i : lamps_.Update(now, *all_way_)) {
    api_->SetLightState(lights_.lights()[i].tls, lamps_.states()[i]);
  }
}

void CoSimulation::HoldForLabCars() {
  // Every lab car in SUMO, where it was last heard of (the Eye or the fleet may skip a step).
  const std::vector<LabCarPose>& cars = lab_->InSumo();
  if (cars.empty() && !lamps_.any_held()) return;
  lab_->claims().Update(cars, [&](MovementId m) {
    if (m.value() >= links_->link_of_movement.size()) return false;
    const auto [light, link] = links_->link_of_movement[m.value()];
    if (light == LinkIndex::kNoLight) return false;
    const std::string& aspect = lamps_.aspects()[light];
    return aspect.empty() || aspect[link] != 'r';
  });
  lamps_.Hold(lab_->claims().held(), *links_);
}

void CoSimulation::InsertRandomVehicles() {
  if (inserted_ || stats_.steps < 1) return;
  // Each expected car in the network as SUMO reported it after the last step.
  const bool all_here = lab_->AllIn(expected_lab_cars_, states_);
  if (!all_here && time_ - SumoTime{} < lab_car_wait_) return;
  if (!all_here) {
    spdlog::warn(
        "traffic: not every lab car was heard from in {:.1f} s: the background vehicles go in "
        "now",
        time_s());
  }
  // Clear of the lab's cars, in SUMO since the first step.
  Add(demand_->RandomVehicles(lab_->Footprints(states_, network_->scale() * 0.05, *sumo_), *sumo_));
  inserted_ = true;
}

void CoSimulation::CountEvents() {
  const SumoStepEvents events = api_->Events();
  for (const std::string& id : events.departed) {
    if (!lab_->IsLab(id)) ++stats_.departed;
  }
  for (const std::string& id : events.arrived) {
    if (lab_->Arrived(id, time_)) continue;
    if (demand_->Arrived(id)) {
      ++stats_.arrived_unplanned;
      spdlog::error("traffic: circulating vehicle {} left the network at {:.2f} s", id, time_s());
    } else {
      ++stats_.arrived_planned;
    }
  }
  for (const std::string& id : events.teleported) {
    ++stats_.teleports;
    spdlog::error("traffic: SUMO teleported {} at {:.2f} s", id, time_s());
  }
  // A collision counts once, when the two start to overlap.
  std::set<std::pair<std::string, std::string>> colliding;
  for (const SumoStepEvents::Collision& c : events.collisions) {
    const auto pair = std::minmax(c.collider, c.victim);
    colliding.emplace(pair.first, pair.second);
    if (colliding_.count({pair.first, pair.second}) != 0) continue;
    if (lab_->IsLab(c.collider) && lab_->IsLab(c.victim)) {
      // Two lab cars as SUMO places them (on its lanes, from their poses): whether they touch
      // is the simulator's (or the track's) to say, not SUMO's.
      ++stats_.lab_overlaps;
      spdlog::info("traffic: at {:.2f} s two lab cars overlap as placed in SUMO: {}", time_s(),
                   c.description);
      continue;
    }
    ++stats_.collisions;
    spdlog::warn("traffic: collision at {:.2f} s: {}{}", time_s(), c.description,
                 lab_->Describe(c.collider, c.victim));
  }
  colliding_ = std::move(colliding);
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
    const bool lab = lab_->IsLab(v.id);
    ReadCache& cache = read_cache_[n];
    const bool same = !lab && n < vehicles_.size() && vehicles_[n].id == v.id;
    if (!lab) {
      cache.lane_changed = !same || cache.info == nullptr || cache.sumo_lane != v.lane;
      if (cache.lane_changed) {
        cache.info = &lanes_->Of(v.lane);
        cache.sumo_lane = v.lane;
      }
      if (!same || cache.size == nullptr) {
        cache.size = &sumo_->TypeSize(v.type);
        cache.object_class = ObjectClass(cache.size->vclass);
      }
    }
    const LaneInfo& info = lab ? lanes_->Of(v.lane) : *cache.info;
    // Lane positions where they matter: the lab's cars, and lanes into, through or out of an
    // all-way stop running now.
    if (lab || all_way_->Near(info)) v.lane_pos = api_->LanePosition(v.id);
    if (lab) {
      lab_->NoteLane(v, *links_, time_);
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
  lab_->Place(lab_cars, now, *api_);
  HoldForLabCars();
  lab_->Move(time_, *sumo_);
  SetLights(now);
  InsertRandomVehicles();
  Add(demand_->DueFlows(time_));
  const double cpu0 = ThreadCpuSeconds();
  api_->Step(0.0);
  stats_.sumo_step_cpu_s += ThreadCpuSeconds() - cpu0;
  time_ = SumoTimeFromSeconds(api_->Time());  // SUMO's seconds: here only
  ++stats_.steps;
  CountEvents();
  ReadVehicles();
  all_way_->Arbitrate(time_, states_, lab_->ids(),
                      AllWayStops::Lights{lamps_.aspects(), lamps_.held()}, *lanes_, *sumo_);
  demand_->ExtendRoutes(stats_.steps, states_, *api_);
  demand_->RerouteBlocked(stats_.steps, time_, states_, *links_, *all_way_, *sumo_);
  stats_.lab_cars_placed = lab_->placed();
  stats_.lab_car_misses = lab_->misses();
  stats_.route_extensions = demand_->route_extensions();
  stats_.reroutes = demand_->reroutes();
  stats_.all_way_grants = all_way_->granted_count();
  stats_.all_way_lapsed = all_way_->lapsed_count();
  return vehicles_;
}

}  // namespace autodrive::traffic
