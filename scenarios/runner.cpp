#include "scenarios/runner.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <numbers>
#include <numeric>
#include <thread>

#include "scenarios/compose.h"
#include "scenarios/metrics.h"
#include "scenarios/recorder.h"
#include "scenarios/report_html.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/lockstep.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/process.h"
#include "common/shutdown.h"
#include "maps/map_io.h"
#include "maps/polyline.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/variability.h"

#ifndef AUTODRIVE_VERSION
#define AUTODRIVE_VERSION "unknown"
#endif

namespace autodrive::scenarios {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The side names a city file's groups use for approaches, by approach id (1 east ... 4 south).
constexpr const char* kApproachNames[] = {"", "east", "north", "west", "south"};

// Which heads show which group: a head listed in the intersection's `heads` shows that group;
// any other shows the group of its approach (docs/scm.md).
std::vector<RunWorld::GroupHeads> GroupHeads(const YAML::Node& city, const maps::Map& map) {
  std::vector<RunWorld::GroupHeads> out;
  for (const auto& xc : city["intersections"]) {
    const std::string name = xc["name"].as<std::string>();
    const auto x = std::find_if(map.intersections.begin(), map.intersections.end(),
                                [&](const maps::Intersection& y) { return y.name == name; });
    if (x == map.intersections.end()) continue;
    std::map<int, int> head_group;
    for (const auto& h : xc["heads"]) head_group[h["head"].as<int>()] = h["group"].as<int>();
    for (const auto& g : xc["groups"]) {
      RunWorld::GroupHeads gh{static_cast<int>(x->id.value()), g["id"].as<int>(), {}};
      std::set<int> approaches;
      for (const auto& a : g["approaches"]) {
        for (int i = 1; i <= 4; ++i) {
          if (a.as<std::string>() == kApproachNames[i]) approaches.insert(i);
        }
      }
      for (const auto& m : g["movements"]) {
        for (const maps::Movement& mv : map.movements) {
          if (mv.name == m.as<std::string>())
            approaches.insert(static_cast<int>(mv.from_approach.value()));
        }
      }
      for (const SignalHeadId h : x->signal_heads) {
        const auto over = head_group.find(static_cast<int>(h.value()));
        const bool shows =
            over != head_group.end()
                ? over->second == gh.group
                : approaches.contains(static_cast<int>(map.signal_head(h).approach.value()));
        if (shows) gh.heads.push_back(static_cast<int>(h.value()));
      }
      out.push_back(std::move(gh));
    }
  }
  return out;
}

// The lane's id in the intersection's MAP message (docs/messaging.md): per approach, in the
// map's order, its ingress lanes then its egress lanes, from 1; 0 when not one of them.
std::uint32_t MapLaneId(const maps::Intersection& x, LaneId lane) {
  std::uint32_t i = 0;
  for (const maps::Approach& a : x.approaches) {
    for (const LaneId l : a.ingress) {
      ++i;
      if (l == lane) return i;
    }
    for (const LaneId l : a.egress) {
      ++i;
      if (l == lane) return i;
    }
  }
  return 0;
}

std::vector<int> HeadsFacing(const maps::Map& map, const maps::Lane& lane) {
  std::vector<int> heads;
  if (!lane.ingress_of) return heads;
  for (const SignalHeadId h : map.intersection(*lane.ingress_of).signal_heads) {
    if (map.signal_head(h).approach == lane.ingress_approach) {
      heads.push_back(static_cast<int>(h.value()));
    }
  }
  return heads;
}

Points RoutePoints(const maps::Map& map, const std::vector<std::string>& route) {
  Points out;
  const maps::Lane* before = nullptr;
  for (const std::string& name : route) {
    const maps::Lane* lane = map.FindLane(name);
    if (before != nullptr) {
      for (const MovementId m : before->movements_out) {
        if (map.movement(m).to == lane->id) {
          out.insert(out.end(), map.movement(m).path.begin(), map.movement(m).path.end());
        }
      }
    }
    out.insert(out.end(), lane->centreline.begin(), lane->centreline.end());
    before = lane;
  }
  return out;
}

RunWorld MakeWorld(const Scenario& scenario, const vehicle_sim::SimConfig& sim,
                   const maps::Map& map, const YAML::Node& city) {
  RunWorld w;
  for (const VehicleSpec& v : scenario.vehicles) {
    const auto it = std::find_if(sim.vehicles.begin(), sim.vehicles.end(),
                                 [&](const auto& c) { return c.name == v.name; });
    const vehicle_sim::VehicleParams& p = it->params;
    w.cars.push_back({v.name, p.body_length_m, p.body_width_m, p.body_centre_ahead_of_rear_axle_m,
                      p.top_speed_mps, RoutePoints(map, v.DrivenRoute()), v.goal_tolerance_m});
    if (v.laps > 1) {
      // Lap k ends where lap k + 1's first lane starts (the last lap at the route's end).
      std::vector<std::string> lanes;
      const double first = maps::PolylineLength(map.FindLane(v.route.front())->centreline);
      for (int lap = 1; lap < v.laps; ++lap) {
        lanes.insert(lanes.end(), v.route.begin(), v.route.end());
        std::vector<std::string> to_next = lanes;
        to_next.push_back(v.route.front());
        w.cars.back().lap_ends_m.push_back(maps::PolylineLength(RoutePoints(map, to_next)) - first);
      }
      w.cars.back().lap_ends_m.push_back(maps::PolylineLength(w.cars.back().route));
    }
    if (v.goal) {
      w.cars.back().goal_pose = Eigen::Vector3d(v.goal->x_m, v.goal->y_m, v.goal->yaw_rad);
      w.cars.back().goal_tolerance_m = v.goal->tolerance_m;
      w.cars.back().goal_tolerance_rad = v.goal->tolerance_rad;
    }
  }
  const maps::Map world_map = vehicle_sim::SimulatedMap(sim, map);
  for (std::size_t i = 0; i < world_map.obstacles.size(); ++i) {
    w.statics.push_back(
        {world_map.obstacles[i].kind, std::to_string(i), world_map.obstacles[i].footprint});
  }
  // The poles of the signal heads and signs, as the simulator's world stands them (heads
  // first, then signs): a car can touch them too. Octagons about each pole's circle.
  const std::vector<vehicle_sim::Cylinder> poles =
      vehicle_sim::GeometryFromMap(world_map, sim.world.scene).cylinders;
  for (std::size_t i = 0; i < poles.size(); ++i) {
    Points octagon;
    const double r = poles[i].radius_m / std::cos(std::numbers::pi / 8);
    for (int k = 0; k < 8; ++k) {
      const double a = std::numbers::pi / 8 + k * std::numbers::pi / 4;
      octagon.push_back(poles[i].centre_M + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
    }
    const std::size_t heads = world_map.signal_heads.size();
    w.statics.push_back({"pole",
                         i < heads ? fmt::format("signal_{}", world_map.signal_heads[i].id.value())
                                   : fmt::format("sign_{}", world_map.signs[i - heads].id.value()),
                         std::move(octagon)});
  }
  const auto obstacles =
      vehicle_sim::UnmappedObstacles(sim, map, vehicle_sim::SpawnPoses(sim, map));
  for (std::size_t i = 0; i < obstacles.size(); ++i) {
    const auto& o = obstacles[i];
    RunWorld::Static st{"obstacle", o.name.empty() ? std::to_string(i) : o.name,
                        Rectangle({o.x_m, o.y_m}, o.yaw_rad, o.length_m, o.width_m)};
    st.from_s = ToSeconds(o.from_s);
    if (o.until_s) st.until_s = ToSeconds(*o.until_s);
    w.statics.push_back(std::move(st));
  }
  for (const maps::Lane& lane : map.lanes) {
    w.lanes.push_back({lane.name, lane.width_m, lane.centreline});
    if (!lane.stop_line || !lane.ingress_of) continue;
    const maps::Intersection& x = map.intersection(*lane.ingress_of);
    const auto n = lane.centreline.size();
    const Eigen::Vector2d dir = (lane.centreline[n - 1] - lane.centreline[n - 2]).normalized();
    const std::vector<int> heads = HeadsFacing(map, lane);
    w.stop_lines.push_back({lane.name, x.name,
                            x.control == maps::Control::kSignal ? "signal" : "stop", heads,
                            lane.stop_line->left, lane.stop_line->right, dir});
    const auto msg_lane = static_cast<int>(MapLaneId(x, lane.id));
    w.ingress[{static_cast<int>(x.id.value()), msg_lane}] = {static_cast<int>(x.id.value()),
                                                             msg_lane, heads};
  }
  for (const maps::Movement& m : map.movements) {
    w.lanes.push_back({m.name, map.lane(m.from).width_m, m.path});
  }
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const maps::ModuleType type =
          map.cells[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)].type;
      if (type != maps::ModuleType::kOpen && type != maps::ModuleType::kParking) continue;
      const Eigen::Vector2d centre = map.TileCentre({r, c});
      const Eigen::Vector2d half = Eigen::Vector2d::Constant(map.tile_size_m / 2);
      w.open_floors.push_back({centre - half, centre + half});
    }
  }
  w.groups = GroupHeads(city, map);
  return w;
}

// The scenario's events, applied at their steps (or when their trigger holds): operator
// commands to the SCM, V2I requests on a car's behalf, faults of the lights.
class EventPlayer {
 public:
  EventPlayer(const dds::Participant& participant, const Scenario& scenario, const maps::Map& map,
              const RunWorld& world, const std::string& operator_name, const fs::path& log)
      : scenario_(scenario),
        map_(map),
        world_(world),
        log_(log, std::ios::binary | std::ios::trunc),
        applied_(scenario.events.size(), false) {
    order_.resize(scenario.events.size());
    std::iota(order_.begin(), order_.end(), std::size_t{0});
    std::ranges::stable_sort(order_, {}, [&](std::size_t i) { return scenario.events[i].at_s; });
    if (!operator_name.empty()) {
      operator_ = std::make_unique<dds::Writer<msg::OperatorRequest>>(
          participant, dds::topics::OperatorRequests(operator_name));
    }
    requests_ = std::make_unique<dds::Writer<msg::SignalRequest>>(participant,
                                                                  dds::topics::SignalRequests());
    if (std::ranges::any_of(scenario.events,
                            [](const EventSpec& e) { return e.head != 0 || !e.host.empty(); })) {
      faults_ = std::make_unique<dds::Writer<msg::SimFault>>(participant, dds::topics::SimFaults());
    }
  }

  // True once what the events are sent to listens: the light hosts' fault readers (volatile:
  // a fault sent before would be lost).
  [[nodiscard]] bool Ready() const { return !faults_ || faults_->matched_readers() > 0; }

  // Applies every event due at `t` (at or before it, its trigger holding on `poses`, the cars'
  // ground truth of the step; not yet applied), in time order (those of one time in the order
  // listed).
  void Apply(Time t, const std::vector<Recorder::Pose>& poses) {
    for (const std::size_t k : order_) {
      const EventSpec& e = scenario_.events[k];
      if (Time{} + e.at_s > t) break;
      if (applied_[k]) continue;
      std::optional<double> reach;  // the trigger's car's front from its point
      if (e.when) {
        reach = Reach(*e.when, poses);
        if (!reach || *reach > e.when->within_m) continue;
      }
      applied_[k] = true;
      const auto x = std::find_if(map_.intersections.begin(), map_.intersections.end(),
                                  [&](const auto& y) { return y.name == e.intersection; });
      json line{{"t_s", ToSeconds(t)},
                {"at_s", ToSeconds(e.at_s)},
                {"action", e.action},
                {"intersection", e.intersection}};
      if (reach) line["trigger"] = {{"vehicle", e.when->vehicle}, {"distance_m", *reach}};
      if (!e.camera.empty()) {
        // The simulator stops and starts its frames on its own clock (the composed city's
        // `lost_from_s`/`lost_until_s`).
        line.erase("intersection");
        line["camera"] = e.camera;
      } else if (!e.obstacle.empty()) {
        // The simulator places and removes it on its own clock (the composed city's
        // `from_s`/`until_s`): the same step, whatever the network does.
        line.erase("intersection");
        line["obstacle"] = e.obstacle;
      } else if (e.action == "surge") {
        // SUMO sends them as a flow of its demand (the composed city's `traffic.flows`).
        line.erase("intersection");
        line["from"] = e.from;
        if (!e.to.empty()) line["to"] = e.to;
        line["per_hour"] = e.per_hour;
        line["count"] = e.count;
        line["type"] = e.type.empty() ? "nigel" : e.type;
      } else if (!e.host.empty()) {
        dds::Message<msg::SimFault> m;
        m->header.stamp = dds::ToMsg(t);
        dds::SetString(m->header.frame_id, "autodrive-scenario/" + scenario_.name);
        dds::SetString(m->host, e.host);
        m->action = e.action == "link_cut" ? autodrive_msgs_msg_SimFault_Constants_LINK_CUT
                                           : autodrive_msgs_msg_SimFault_Constants_LINK_RESTORE;
        faults_->Write(m);
        line.erase("intersection");
        line["host"] = e.host;
      } else if (e.head != 0) {
        dds::Message<msg::SimFault> m;
        m->header.stamp = dds::ToMsg(t);
        dds::SetString(m->header.frame_id, "autodrive-scenario/" + scenario_.name);
        m->head = static_cast<std::uint32_t>(e.head);
        m->action = e.action == "unplug"     ? autodrive_msgs_msg_SimFault_Constants_UNPLUG_HEAD
                    : e.action == "plug"     ? autodrive_msgs_msg_SimFault_Constants_PLUG_HEAD
                    : e.fault == "burnt_out" ? autodrive_msgs_msg_SimFault_Constants_FAIL_LAMP
                    : e.fault == "stuck_on"  ? autodrive_msgs_msg_SimFault_Constants_STICK_LAMP
                                             : autodrive_msgs_msg_SimFault_Constants_REPAIR_LAMP;
        m->lamp = e.lamp == "red"      ? autodrive_msgs_msg_SimFault_Constants_RED
                  : e.lamp == "yellow" ? autodrive_msgs_msg_SimFault_Constants_YELLOW
                  : e.lamp == "green"  ? autodrive_msgs_msg_SimFault_Constants_GREEN
                                       : 0;
        faults_->Write(m);
        line.erase("intersection");
        line["head"] = e.head;
        if (!e.lamp.empty()) line["lamp"] = e.lamp;
        if (!e.fault.empty()) line["fault"] = e.fault;
      } else if (e.action == "mode" || e.action == "plan") {
        dds::Message<msg::OperatorRequest> m;
        m->header.stamp = dds::ToMsg(t);
        dds::SetString(m->client_id, "autodrive-scenario/" + scenario_.name);
        m->request_id = ++request_id_;
        dds::SetString(m->command, e.action);
        m->intersection_id = x->id.value();
        dds::ResizeSequence(m->arguments, 2);
        dds::SetString(m->arguments._buffer[0].key, "intersection");
        dds::SetString(m->arguments._buffer[0].value, e.intersection);
        dds::SetString(m->arguments._buffer[1].key, e.action);
        dds::SetString(m->arguments._buffer[1].value, e.action == "mode" ? e.mode : e.plan);
        operator_->Write(m);
        line[e.action] = e.action == "mode" ? e.mode : e.plan;
      } else {
        const auto v = std::find_if(scenario_.vehicles.begin(), scenario_.vehicles.end(),
                                    [&](const auto& c) { return c.name == e.vehicle; });
        // The car's lanes into and out of the intersection, from its route.
        std::uint32_t in = 0, out = 0;
        for (std::size_t i = 0; i < v->route.size(); ++i) {
          const maps::Lane* lane = map_.FindLane(v->route[i]);
          if (lane->ingress_of == x->id) {
            in = MapLaneId(*x, lane->id);
            if (i + 1 < v->route.size()) out = MapLaneId(*x, map_.FindLane(v->route[i + 1])->id);
          }
        }
        dds::Message<msg::SignalRequest> m;
        m->header.stamp = dds::ToMsg(t);
        dds::SetString(m->vehicle_id, e.vehicle);
        std::uint32_t& id = request_ids_[e.vehicle];
        if (e.action != "cancel") ++id;
        m->request_id = id;
        m->request_type = e.action == "preempt" ? 2 : e.action == "priority" ? 1 : 4;
        m->vehicle_role = e.action == "preempt" ? 2 : e.action == "priority" ? 1 : 0;
        m->intersection_id = x->id.value();
        m->in_lane_id = in;
        m->out_lane_id = out;
        m->eta = dds::ToMsg(t + std::chrono::seconds(5));
        m->duration = dds::ToMsg(Duration{std::chrono::seconds(5)});
        requests_->Write(m);
        line["vehicle"] = e.vehicle;
        line["request_id"] = id;
        line["in_lane"] = in;
      }
      // Flushed at once: the report is made from the file before the player is gone.
      log_ << line.dump() << '\n' << std::flush;
    }
  }

 private:
  const Scenario& scenario_;
  const maps::Map& map_;
  const RunWorld& world_;
  std::ofstream log_;
  std::unique_ptr<dds::Writer<msg::OperatorRequest>> operator_;
  std::unique_ptr<dds::Writer<msg::SignalRequest>> requests_;
  std::unique_ptr<dds::Writer<msg::SimFault>> faults_;  // when an event faults a head
  // How far the trigger's car's front is from its point; none before its first pose.
  std::optional<double> Reach(const TriggerSpec& when,
                              const std::vector<Recorder::Pose>& poses) const {
    for (std::size_t i = 0; i < world_.cars.size(); ++i) {
      const RunWorld::Car& car = world_.cars[i];
      if (car.name != when.vehicle || !poses[i].known) continue;
      const Recorder::Pose& p = poses[i];
      return (car.FrontAt(p.x_m, p.y_m, p.yaw_rad) - Eigen::Vector2d(when.x_m, when.y_m)).norm();
    }
    return std::nullopt;
  }

  std::vector<std::size_t> order_;  // the events' indices in time order
  std::vector<bool> applied_;       // by index
  std::uint64_t request_id_ = 0;
  std::map<std::string, std::uint32_t> request_ids_;
};

std::string MakePartition() {
  static std::atomic<int> n{0};
  char host[64] = {};
  gethostname(host, sizeof host - 1);
  std::string h = host;
  for (char& c : h) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return fmt::format("scenario_{}_{}_{}", h, getpid(), n++);
}

}  // namespace

const std::vector<std::string>& VolatileReportKeys() {
  static const std::vector<std::string> keys{"invocation"};
  return keys;
}

RunResult RunScenario(const RunOptions& options) {
  const auto wall_start = std::chrono::steady_clock::now();
  Scenario scenario = LoadScenario(options.scenario_file);
  if (options.seed) scenario.seed = *options.seed;
  const vehicle_sim::SimCity base = vehicle_sim::LoadSimCity(scenario.city);
  const maps::Map map = maps::LoadMapOrLayout(base.map_path);

  const fs::path out = fs::absolute(options.out_dir).lexically_normal();
  fs::create_directories(out);
  for (const char* stale :
       {"run", "logs", "report.json", "report.html", "launcher.log", "recording.mcap"}) {
    fs::remove_all(out / stale);
  }
  const fs::path city_file = out / "city.yaml";
  const ComposedCity composed = ComposeCity(scenario, options.scenario_file, map, city_file,
                                            out / "run", out / "logs", options.bin_dir);
  config::WriteFile(city_file, composed.yaml);
  // The composed city as its programs will load it (refused here, before anything starts).
  const vehicle_sim::SimCity sim_city = vehicle_sim::LoadSimCity(city_file.string());
  RunWorld world = MakeWorld(scenario, sim_city.sim, map, YAML::LoadFile(city_file.string()));

  dds::ProgramOptions dds_options("/autodrive/scenario");
  const std::string partition = options.partition.empty() ? MakePartition() : options.partition;
  dds_options.set_partition(partition);
  dds::Participant participant(dds_options.Participant());
  std::vector<std::string> names;
  for (const VehicleSpec& v : scenario.vehicles) names.push_back(v.name);
  Recorder recorder(participant, names, map, composed.traffic, out / "logs");
  EventPlayer events(participant, scenario, map, world, composed.operator_name,
                     out / "logs" / "scenario_events.jsonl");

  // The city, through the launcher. TZ=UTC: the SCM's schedule reads the simulated time (from
  // 0, 1970-01-01 00:00) in local time, which must not depend on the machine.
  ChildOptions child_options;
  child_options.extra_env = {"TZ=UTC", fmt::format("{}={}", kStopWithParentEnv, getpid())};
  child_options.output_file = out / "launcher.log";
  child_options.own_session = true;
  std::vector<std::string> launcher_argv{(options.bin_dir / "autodrive-city").string(), "up",
                                         city_file.string(), "--partition", partition};
  if (options.record) {
    // The whole run as a rosbag2-compatible MCAP (docs/recording.md).
    launcher_argv.insert(launcher_argv.end(), {"--record", (out / "recording.mcap").string()});
  }
  ChildProcess launcher = ChildProcess::Start(launcher_argv, child_options);
  spdlog::info("{}: city {} up on partition {} (log: {})", scenario.name, composed.city_name,
               partition, (out / "launcher.log").string());

  std::atomic<bool> stop{false};
  std::atomic<bool> launcher_exited{false};
  std::atomic<bool> done{false};
  std::optional<int> launcher_code;
  // A process of the city that exits on its own before the simulator ends the run (an agent
  // that fails, or ends before it registered, which the simulator would wait for for good),
  // from the launcher's status.json.
  std::mutex exited_mutex;
  std::string exited;
  std::atomic<std::chrono::steady_clock::rep> last_step_wall{
      std::chrono::steady_clock::now().time_since_epoch().count()};
  const auto check_processes = [&] {
    std::ifstream in(out / "run" / "status.json");
    if (!in) return;
    try {
      const json status = json::parse(in);
      for (const json& p : status.at("processes")) {
        // At the run's end every process exits too: only a run that no longer steps (none
        // for 5 s) is ended for it.
        if (p.value("exits", 0) > 0 &&
            std::chrono::steady_clock::now().time_since_epoch().count() - last_step_wall.load() >
                std::chrono::steady_clock::duration(std::chrono::seconds(5)).count()) {
          std::lock_guard lock(exited_mutex);
          exited = fmt::format("{} {} (its log: {})", p.value("name", "?"),
                               p.value("detail", "exited"), p.value("log", "?"));
          stop.store(true);
          return;
        }
      }
    } catch (const std::exception&) {
      // being replaced: read it again next time
    }
  };
  std::thread watcher([&] {
    for (int tick = 0; !done.load(); ++tick) {
      if (options.stop != nullptr && options.stop->load()) stop.store(true);
      if (tick % 10 == 9) check_processes();
      if (!launcher_exited.load()) {
        if (const auto code = launcher.Wait(std::chrono::milliseconds(100))) {
          launcher_code = code;
          launcher_exited.store(true);
          stop.store(true);
        }
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    }
  });

  std::string end_reason = "time_limit";
  Time last_step{};
  bool goals_end = false;
  std::vector<RouteProgress> routes;  // each car's, as the metrics measure it
  for (const RunWorld::Car& car : world.cars) routes.emplace_back(car, MetricConstants{});
  std::int64_t steps = 0;
  std::string failure;
  try {
    // The simulator's, the lights' and the SCM's writers matched before we register (the
    // simulator's first step waits for us): nothing of the first step is missed.
    const auto match_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (!stop.load() &&
           !(recorder.WaitForWriters(std::chrono::milliseconds(500)) && events.Ready())) {
      if (std::chrono::steady_clock::now() > match_deadline) {
        throw InputError(fmt::format(
            "{} in 120 s (see {})",
            events.Ready() ? "the city's simulator, lights or SCM did not come up"
                           : "no light host reads the scenario's faults (are its heads simulated?)",
            (out / "launcher.log").string()));
      }
    }
    const dds::LockstepRun lockstep =
        dds::RunLockstepController(participant, std::string(kRunnerController), stop, [&](Time t) {
          ++steps;
          last_step = t;
          last_step_wall.store(std::chrono::steady_clock::now().time_since_epoch().count());
          recorder.Take(t);
          events.Apply(t, recorder.poses());
          if (options.progress && (t - Time{}) % std::chrono::seconds(10) == Duration{0} &&
              t != Time{}) {
            std::fprintf(stderr, "%s: %.0f of %.0f simulated s\n", scenario.name.c_str(),
                         ToSeconds(t), ToSeconds(scenario.time_limit_s));
          }
          // Every car with a route at its goal and standing: the run is over.
          if (scenario.end.goals_reached) {
            bool any = false, all = true;
            for (std::size_t i = 0; i < world.cars.size(); ++i) {
              const RunWorld::Car& car = world.cars[i];
              const Recorder::Pose& p = recorder.poses()[i];
              if (p.known) routes[i].Update(p.x_m, p.y_m);
              if (!car.HasGoal()) continue;
              any = true;
              const bool at_goal = car.route.empty() ? car.AtGoal(p.x_m, p.y_m, p.yaw_rad)
                                                     : routes[i].AtGoal(p.x_m, p.y_m, p.yaw_rad);
              all = all && p.known && std::abs(p.speed_mps) < 0.01 && at_goal;
            }
            if (any && all) {
              goals_end = true;
              stop.store(true);
            }
          }
        });
    if (goals_end) {
      end_reason = "goals_reached";
    } else if (options.stop != nullptr && options.stop->load()) {
      end_reason = "interrupted";
    } else if (!lockstep.ended) {
      end_reason = "failed";
      std::lock_guard lock(exited_mutex);
      failure = !exited.empty() ? "the city's process " + exited + " before the run ended"
                : launcher_exited.load()
                    ? fmt::format(
                          "the city ended before the simulator did (the launcher "
                          "exited with {}; see {})",
                          *launcher_code, (out / "launcher.log").string())
                    : "the run was stopped";
    }
  } catch (const std::exception& e) {
    end_reason = "failed";
    failure = e.what();
    // The simulator gone: what it said last (its error) is the cause.
    const fs::path sim_log = out / "run" / "logs" / "sim.log";
    std::ifstream in(sim_log);
    std::string last, line;
    while (std::getline(in, line)) {
      if (!line.empty() && line.rfind("====", 0) != 0) last = line;
    }
    if (in.eof() && !last.empty() && last.find("[info]") == std::string::npos) {
      failure +=
          fmt::format("; the simulator's last words: {} (its log: {})", last, sim_log.string());
    }
  }
  // Down, whatever happened: the launcher stops the city in order (SIGTERM), then we wait.
  done.store(true);
  watcher.join();
  if (!launcher_exited.load()) {
    if (end_reason == "time_limit") {
      // The simulator ended the run: the launcher exits by itself once every process did.
      launcher_code = launcher.Wait(std::chrono::seconds(60));
    }
    if (!launcher_code) launcher_code = launcher.Stop(std::chrono::seconds(30));
  }
  recorder.Close();

  RunResult result;
  world.end_s = ToSeconds(last_step);
  config::WriteFile(out / "logs" / "world.json", world.ToJson().dump() + "\n");
  json metrics = ComputeMetrics(world, out / "logs");
  json expectations = json::array();
  for (const auto& [metric, text] : scenario.expect) {
    const Expectation e = ParseExpectation(text);
    const json& value = metrics["run"][metric];
    const bool held = value.is_number() && e.Holds(value.get<double>());
    expectations.push_back(
        {{"metric", metric}, {"expect", text}, {"value", value}, {"held", held}});
    if (!held) result.failures.push_back(fmt::format("{} {} (got {})", metric, text, value.dump()));
  }
  if (end_reason == "failed") result.failures.insert(result.failures.begin(), failure);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  json report;
  report["scenario"] = {{"name", scenario.name},
                        {"description", scenario.description},
                        {"file", fs::absolute(options.scenario_file).lexically_normal().string()},
                        {"text", config::ReadFile(options.scenario_file)}};
  report["seed"] = scenario.seed;
  report["city"] = composed.city_name;
  report["versions"] = {{"autodrive", AUTODRIVE_VERSION}};
  report["end"] = {{"reason", end_reason}, {"t_s", world.end_s}, {"failure", failure}};
  report["metrics"] = metrics;
  report["expect"] = expectations;
  report["passed"] = result.failures.empty();
  report["invocation"] = {
      {"command_line", options.command_line},
      {"out", out.string()},
      {"partition", partition},
      {"wall_s", std::round(wall_s * 1000) / 1000},
      {"real_time_factor", wall_s > 0 ? std::round(world.end_s / wall_s * 1000) / 1000 : 0.0},
      {"launcher_exit", launcher_code ? *launcher_code : -1}};
  config::WriteFile(out / "report.json", report.dump(2) + "\n");
  config::WriteFile(out / "report.html", ReportHtml(report, out));
  result.report = std::move(report);
  if (end_reason == "interrupted") {
    result.exit_code = 130;
  } else if (end_reason == "failed") {
    result.exit_code = 2;
  } else {
    result.exit_code = result.failures.empty() ? 0 : 1;
  }
  return result;
}

}  // namespace autodrive::scenarios
