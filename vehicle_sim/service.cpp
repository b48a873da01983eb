#include "vehicle_sim/service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/lockstep.h"
#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "vehicle_sim/cameras.h"
#include "vehicle_sim/replay.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/traffic.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

namespace {

namespace topics = dds::topics;

// A car and a background object that have not touched for this long touch anew: a car pressed
// against one is one collision, not one per step that its contact flickers.
constexpr Duration kTouchGap = std::chrono::seconds(1);

void SetHeader(std_msgs_msg_dds__Header_& header, Time stamp, const char* frame) {
  header.stamp = dds::ToMsg(stamp);
  dds::BorrowString(header.frame_id, frame);
}

// One car's DDS endpoints and what it was last told.
struct CarEndpoints {
  CarEndpoints(const dds::Participant& p, VehicleId id, CommandNoise command_noise)
      : name(VehicleName(id)),
        throttle(p, topics::Throttle(id)),
        steering(p, topics::Steering(id)),
        left_encoder(p, topics::LeftEncoder(id)),
        right_encoder(p, topics::RightEncoder(id)),
        ips(p, topics::Ips(id)),
        imu(p, topics::Imu(id)),
        lidar(p, topics::Lidar(id)),
        ground_truth(p, topics::GroundTruth(id)),
        throttle_command(p, topics::ThrottleCommand(id)),
        steering_command(p, topics::SteeringCommand(id)),
        headlights_command(p, topics::HeadlightsCommand(id)),
        indicators_command(p, topics::IndicatorsCommand(id)),
        noise(std::move(command_noise)) {}

  std::string name;
  dds::Writer<msg::Float32> throttle, steering;
  dds::Writer<msg::JointState> left_encoder, right_encoder;
  dds::Writer<msg::Point> ips;
  dds::Writer<msg::Imu> imu;
  dds::Writer<msg::LaserScan> lidar;
  dds::Writer<msg::TrackedVehicle> ground_truth;
  dds::Reader<msg::Float32> throttle_command, steering_command;
  dds::Reader<msg::Int32> headlights_command, indicators_command;

  // Waits until every reader of every writer above has acknowledged what it was sent.
  void WaitForAcks(std::chrono::steady_clock::duration timeout) const {
    bool ok = throttle.WaitForAcks(timeout) && steering.WaitForAcks(timeout) &&
              left_encoder.WaitForAcks(timeout) && right_encoder.WaitForAcks(timeout) &&
              ips.WaitForAcks(timeout) && imu.WaitForAcks(timeout) && lidar.WaitForAcks(timeout) &&
              ground_truth.WaitForAcks(timeout);
    if (!ok) spdlog::warn("{}: a reader did not acknowledge its data in time", name);
  }

  VehicleCommand command;
  CommandNoise noise;
  std::int32_t headlights = 0;
  std::int32_t indicators = 0;
  Duration last_command{0};
  bool timed_out = false;
  bool ever_commanded = false;
};

// Renders one camera's frames on its own thread (real-time mode), so that the physics loop does
// not wait for them: a frame that falls due while the last one is still being rendered is
// dropped and counted.
class CameraWorker {
 public:
  using Publish = std::function<void(const Image&, Time)>;
  CameraWorker(SimCameras& cameras, std::size_t k, Publish publish)
      : cameras_(cameras), k_(k), publish_(std::move(publish)), thread_([this] { Loop(); }) {}
  ~CameraWorker() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  CameraWorker(const CameraWorker&) = delete;
  CameraWorker& operator=(const CameraWorker&) = delete;

  // Hands over the camera's frame from the cameras' last snapshot; false (dropped) when busy.
  bool Offer(std::uint64_t noise_seed, Time stamp) {
    std::lock_guard lock(mutex_);
    if (busy_) {
      ++dropped_;
      return false;
    }
    cameras_.MakeJob(k_, noise_seed, job_);
    stamp_ = stamp;
    busy_ = true;
    wake_.notify_one();
    return true;
  }
  std::int64_t dropped() const {
    std::lock_guard lock(mutex_);
    return dropped_;
  }

 private:
  void Loop() {
    std::unique_lock lock(mutex_);
    while (true) {
      wake_.wait(lock, [this] { return stop_ || busy_; });
      if (stop_) return;
      lock.unlock();
      cameras_.Render(k_, job_, image_);
      publish_(image_, stamp_);
      lock.lock();
      busy_ = false;
    }
  }

  SimCameras& cameras_;
  std::size_t k_;
  Publish publish_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool busy_ = false;  // a job is waiting or being rendered (job_ and stamp_ are the worker's)
  bool stop_ = false;
  std::int64_t dropped_ = 0;
  SimCameras::Job job_;
  Time stamp_;
  Image image_;
  std::thread thread_;  // last: started when everything above is ready
};

}  // namespace

struct SimService::Impl {
  ServiceOptions options;
  World world;
  std::vector<SimVehicleConfig> cars_config;
  std::vector<std::unique_ptr<CarEndpoints>> cars;
  std::vector<SensorSuite> suites;
  dds::Writer<msg::Clock> clock;
  std::vector<std::pair<SignalHeadId, std::unique_ptr<dds::Reader<msg::Int32>>>> lamp_readers;
  mutable std::mutex lamps_mutex;
  std::map<SignalHeadId, LampState> lamps;
  Time origin;  // the ROS time of simulated time 0
  std::int64_t steps_per_period = 1;
  std::vector<DynamicBox> car_boxes;  // every car's box after a step (id: its index)
  // What car i's LIDAR sees: the background boxes it may reach in this period (the head,
  // `lidar_traffic[i]` of them, chosen at the period's start), then `car_boxes` (each step).
  std::vector<std::vector<DynamicBox>> lidar_boxes;
  std::vector<std::size_t> lidar_traffic;
  SensorReadings readings;
  std::ostream* log = nullptr;
  // Cameras: one writer per camera, in `cameras`' order.
  std::unique_ptr<SimCameras> cameras;
  std::vector<std::unique_ptr<dds::Writer<msg::Image>>> camera_writers;
  std::vector<std::size_t> due;
  std::vector<CarLights> lights;
  std::vector<HeadLamps> head_lamps;
  Image image;
  std::uint64_t seed = 1;
  std::vector<std::unique_ptr<CameraWorker>> workers;  ///< real-time mode: one per camera
  // Background traffic (`options.traffic`): the newest TrafficObjects (`traffic_newest`;
  // `traffic_incoming` takes, so that a failed take never spoils the newest), its objects as
  // it gave them, and where they are this period: boxes for the LIDARs and the physics (ids
  // after the cars'), looks for the cameras.
  std::unique_ptr<dds::Reader<msg::TrafficObjects>> traffic_reader;
  dds::Message<msg::TrafficObjects> traffic_newest, traffic_incoming;
  std::vector<TrafficObject> traffic;
  Time traffic_stamp;
  std::optional<Duration> traffic_placed_after;  // the extrapolation the placed poses have
  std::vector<DynamicBox> traffic_boxes;
  std::vector<RenderTraffic> traffic_looks;
  std::int64_t traffic_messages = 0;
  std::int64_t traffic_bad_messages = 0;
  // Car and object (its id) touching: when they last touched.
  std::map<std::pair<int, std::string>, Duration> touching;
  std::atomic<std::int64_t> traffic_collisions{0};
  // Lockstep only: the protocol's server side (common/dds/lockstep.h).
  std::unique_ptr<dds::LockstepServer> lockstep;

  Impl(const dds::Participant& participant, const SimCity& city, const maps::Map& map,
       const ServiceOptions& o)
      : options(o),
        world(SimulatedMap(city.sim, map), city.sim.world),
        cars_config(city.sim.vehicles),
        clock(participant, topics::Clock()) {
    AUTODRIVE_THROW_UNLESS(o.control_period >= world.options().step,
                           "the control period " << ToSeconds(o.control_period)
                                                 << " s is shorter than the physics step "
                                                 << ToSeconds(world.options().step) << " s");
    AUTODRIVE_THROW_UNLESS(o.real_time_factor > 0 && std::isfinite(o.real_time_factor),
                           "the real-time factor must be positive, got " << o.real_time_factor);
    o.Validate();
    steps_per_period = o.control_period / world.options().step;
    const std::vector<RigidTransform2> poses = SpawnPoses(city.sim, map);
    const std::vector<UnmappedObstacle> obstacles = UnmappedObstacles(city.sim, map, poses);
    AddObstacles(obstacles, world);
    for (const UnmappedObstacle& ob : obstacles) {
      spdlog::info("unmapped obstacle: {:.2f} x {:.2f} x {:.2f} m at ({:.3f}, {:.3f}), {:.3f} rad",
                   ob.length_m, ob.width_m, ob.height_m, ob.x_m, ob.y_m, ob.yaw_rad);
    }
    for (std::size_t i = 0; i < cars_config.size(); ++i) {
      const SimVehicleConfig& c = cars_config[i];
      const int index = world.AddVehicle(c.params, poses[i]);
      suites.emplace_back(EffectiveSensors(city.sim, i), index, city.sim.seed);
      cars.push_back(std::make_unique<CarEndpoints>(
          participant, ParseVehicleName(c.name),
          CommandNoise(city.sim.variability, c.params, city.sim.seed, index)));
    }
    seed = city.sim.seed;
    cameras = std::make_unique<SimCameras>(city.sim, map, world);
    for (const SimCamera& cam : cameras->cameras()) {
      camera_writers.push_back(std::make_unique<dds::Writer<msg::Image>>(
          participant, !cam.vehicle_id ? topics::OverheadCamera(cam.name)
                       : cam.front     ? topics::FrontCamera(*cam.vehicle_id)
                                       : topics::RearCamera(*cam.vehicle_id)));
      spdlog::info("camera {}: {} x {} at {:.3g} Hz", cam.name, cam.intrinsics.width_px,
                   cam.intrinsics.height_px, 1.0 / ToSeconds(cam.period));
    }
    if (o.mode == SimMode::kRealTime) {
      for (std::size_t k = 0; k < camera_writers.size(); ++k) {
        workers.push_back(std::make_unique<CameraWorker>(
            *cameras, k, [this, k](const Image& im, Time stamp) { PublishImage(k, im, stamp); }));
      }
    }
    for (const maps::SignalHead& head : map.signal_heads) {
      lamp_readers.emplace_back(head.id, std::make_unique<dds::Reader<msg::Int32>>(
                                             participant, topics::SignalState(head.id)));
    }
    if (o.traffic) {
      traffic_reader =
          std::make_unique<dds::Reader<msg::TrafficObjects>>(participant, topics::Traffic());
    }
    if (o.mode == SimMode::kLockstep) {
      lockstep = std::make_unique<dds::LockstepServer>(participant, o.controllers);
    }
    origin = o.mode == SimMode::kRealTime ? WallClock().Now() : Time{};
  }

  Time Stamp(Duration t) const { return origin + t; }

  void TakeLamps() {
    std::lock_guard lock(lamps_mutex);
    for (auto& [id, reader] : lamp_readers) {
      while (auto m = reader->TakeOne()) lamps[id] = (*m)->data;
    }
  }

  void TakeCommands() {
    const Duration now = world.time();
    for (std::size_t i = 0; i < cars.size(); ++i) {
      CarEndpoints& car = *cars[i];
      bool fresh = false;
      while (auto m = car.throttle_command.TakeOne()) {
        if (std::isfinite((*m)->data)) {
          car.command.throttle = std::clamp(static_cast<double>((*m)->data), -1.0, 1.0);
          fresh = true;
        }
      }
      while (auto m = car.steering_command.TakeOne()) {
        if (std::isfinite((*m)->data)) {
          car.command.steering = std::clamp(static_cast<double>((*m)->data), -1.0, 1.0);
          fresh = true;
        }
      }
      while (auto m = car.headlights_command.TakeOne()) car.headlights = (*m)->data;
      while (auto m = car.indicators_command.TakeOne()) car.indicators = (*m)->data;
      if (fresh) {
        car.last_command = now;
        car.ever_commanded = true;
        if (car.timed_out) spdlog::info("{}: commands again", car.name);
        car.timed_out = false;
      } else if (car.ever_commanded && !car.timed_out &&
                 now - car.last_command > options.command_timeout) {
        car.timed_out = true;
        spdlog::warn("{}: no command for {:.3f} s: holding still", car.name,
                     ToSeconds(options.command_timeout));
      }
      VehicleCommand applied = car.noise.Apply(car.command);
      if (car.timed_out) applied.throttle = 0.0;
      world.SetCommand(static_cast<int>(i), applied);
    }
  }

  // The newest background traffic, placed for this period: as the message has it in lockstep
  // and fast mode (reproducible), moved along its heading by its speed for the message's age
  // in real time (at most kMaxTrafficExtrapolation). Nothing changes while no message came and
  // the poses stay where they are.
  void TakeTraffic() {
    if (!traffic_reader) return;
    bool fresh = false;
    while (traffic_reader->TakeOne(traffic_incoming)) {
      std::swap(traffic_newest, traffic_incoming);
      fresh = true;
    }
    const Time now = Stamp(world.time());
    if (fresh) {
      ++traffic_messages;
      const TrafficReadReport report = ReadTrafficObjects(*traffic_newest, traffic);
      std::string problem = report.first_problem;
      try {
        traffic_stamp = dds::FromMsg(traffic_newest->header.stamp);
      } catch (const InputError& e) {
        traffic_stamp = now;  // taken as it is
        if (problem.empty()) problem = std::string("its stamp: ") + e.what();
      }
      if (!problem.empty() && ++traffic_bad_messages % 100 == 1) {
        spdlog::warn("background traffic: message {} ({} bad so far): {} object(s) left out; {}",
                     traffic_messages, traffic_bad_messages, report.skipped, problem);
      }
      if (traffic_messages == 1) {
        spdlog::info("background traffic: {} object(s) in the first message", traffic.size());
      }
    }
    const Duration after =
        options.mode == SimMode::kRealTime ? TrafficExtrapolation(traffic_stamp, now) : Duration{0};
    if (!fresh && traffic_placed_after == after) return;
    traffic_placed_after = after;
    const auto first_id = static_cast<std::uint32_t>(cars.size());
    traffic_boxes.clear();
    traffic_looks.clear();
    for (std::size_t k = 0; k < traffic.size(); ++k) {
      const Eigen::Isometry3d X_MO = TrafficPoseAfter(traffic[k], after);
      traffic_boxes.push_back(
          TrafficBox(traffic[k], X_MO, BoxId(first_id + static_cast<std::uint32_t>(k))));
      if (!cameras->empty()) traffic_looks.push_back(TrafficLook(traffic[k], X_MO));
    }
    world.SetTraffic(traffic_boxes);
  }

  // For each car, the background boxes its LIDAR may reach in this period: a city's objects
  // far from every car then cost the LIDARs nothing during the period's steps.
  void ChooseLidarTraffic() {
    lidar_boxes.resize(cars.size());
    lidar_traffic.resize(cars.size());
    for (std::size_t i = 0; i < cars.size(); ++i) {
      lidar_boxes[i].clear();
      suites[i].Reachable(world, traffic_boxes, options.control_period, lidar_boxes[i]);
      lidar_traffic[i] = lidar_boxes[i].size();
    }
  }

  // What the LIDARs see after a step: each car's background boxes of the period (kept), then
  // every car's box.
  void UpdateBoxes() {
    VehicleBoxes(world, car_boxes);
    for (std::size_t i = 0; i < cars.size(); ++i) {
      std::vector<DynamicBox>& seen = lidar_boxes[i];
      seen.erase(seen.begin() + static_cast<std::ptrdiff_t>(lidar_traffic[i]), seen.end());
      seen.insert(seen.end(), car_boxes.begin(), car_boxes.end());
    }
  }

  // A car that touches a background object it did not touch within kTouchGap has run into it:
  // counted and logged.
  void NoteTrafficContacts() {
    const Duration now = world.time();
    for (const TrafficContact& c : world.TrafficContacts()) {
      const TrafficObject& object = traffic.at(static_cast<std::size_t>(c.traffic));
      const auto [it, first] = touching.try_emplace({c.vehicle, object.id}, now);
      if (first || now - it->second > kTouchGap) {
        traffic_collisions.fetch_add(1);
        const Eigen::Vector3d car = world.State(c.vehicle).X_MV.translation();
        const Eigen::Vector3d box = object.X_MO.translation();
        spdlog::warn(
            "{} (at {:.3f}, {:.3f}) ran into background {} '{}' (at {:.3f}, {:.3f}) at t = {:.3f} "
            "s",
            cars.at(static_cast<std::size_t>(c.vehicle))->name, car.x(), car.y(),
            ToString(object.object_class), object.id, box.x(), box.y(), ToSeconds(now));
      }
      it->second = now;
    }
    if (touching.empty()) return;
    std::erase_if(touching, [&](const auto& entry) { return now - entry.second > kTouchGap; });
  }

  void Publish(std::size_t i) {
    CarEndpoints& car = *cars[i];
    const SensorReadings& r = readings;
    if (r.feedback) {
      car.throttle.Write(msg::Float32{static_cast<float>(r.feedback->throttle)});
      car.steering.Write(msg::Float32{static_cast<float>(r.feedback->steering_rad)});
    }
    if (r.encoders) {
      for (int k = 0; k < 2; ++k) {
        const char* frame = k == 0 ? "left_encoder" : "right_encoder";
        msg::JointState js{};
        SetHeader(js.header, Stamp(r.encoders->stamp), frame);
        char* names[1] = {const_cast<char*>(frame)};
        dds::BorrowSequence(js.name, std::span<char*>(names, 1));
        double position[1] = {r.encoders->angle_rad[static_cast<std::size_t>(k)]};
        dds::BorrowSequence(js.position, std::span<double>(position, 1));
        (k == 0 ? car.left_encoder : car.right_encoder).Write(js);
      }
    }
    if (r.ips) {
      const Eigen::Vector3d& p = r.ips->position_m;
      car.ips.Write(msg::Point{p.x(), p.y(), p.z()});
    }
    if (r.imu) {
      const ImuConfig& c = suites[i].config().imu;
      msg::Imu m{};
      SetHeader(m.header, Stamp(r.imu->stamp), "imu");
      const Eigen::Quaterniond& q = r.imu->orientation;
      m.orientation = {q.x(), q.y(), q.z(), q.w()};
      m.angular_velocity = {r.imu->angular_velocity_radps.x(), r.imu->angular_velocity_radps.y(),
                            r.imu->angular_velocity_radps.z()};
      m.linear_acceleration = {r.imu->linear_acceleration_mps2.x(),
                               r.imu->linear_acceleration_mps2.y(),
                               r.imu->linear_acceleration_mps2.z()};
      for (int k = 0; k < 3; ++k) {
        m.orientation_covariance[4 * k] = c.orientation_noise_rad * c.orientation_noise_rad;
        m.angular_velocity_covariance[4 * k] = c.gyro_noise_radps * c.gyro_noise_radps;
        m.linear_acceleration_covariance[4 * k] = c.accel_noise_mps2 * c.accel_noise_mps2;
      }
      car.imu.Write(m);
    }
    if (r.lidar) {
      const LidarScan& s = *r.lidar;
      msg::LaserScan m{};
      SetHeader(m.header, Stamp(s.stamp), "lidar");
      m.angle_min = static_cast<float>(s.angle_min_rad);
      m.angle_increment = static_cast<float>(s.angle_increment_rad);
      m.angle_max = static_cast<float>(
          s.angle_min_rad + (static_cast<double>(s.ranges.size()) - 1) * s.angle_increment_rad);
      m.time_increment = static_cast<float>(s.time_increment_s);
      m.scan_time = static_cast<float>(s.scan_time_s);
      m.range_min = static_cast<float>(s.range_min_m);
      m.range_max = static_cast<float>(s.range_max_m);
      auto& ranges = const_cast<std::vector<float>&>(s.ranges);
      dds::BorrowSequence(m.ranges, std::span<float>(ranges));
      car.lidar.Write(m);
    }
  }

  void PublishGroundTruth(std::size_t i) {
    const VehicleState& s = world.State(static_cast<int>(i));
    msg::TrackedVehicle m{};
    dds::BorrowString(m.vehicle_id, cars[i]->name.c_str());
    m.source = autodrive_msgs_msg_TrackedVehicle_Constants_SIM_GROUND_TRUTH;
    m.observed = dds::ToMsg(Stamp(world.time()));
    m.pose.pose = dds::ToMsg(s.X_MV);
    m.twist.twist.linear = {s.v_V_mps.x(), s.v_V_mps.y(), s.v_V_mps.z()};
    m.twist.twist.angular = {s.w_V_radps.x(), s.w_V_radps.y(), s.w_V_radps.z()};
    dds::BorrowString(m.map_lane_id, "");
    cars[i]->ground_truth.Write(m);
  }

  // The frames of the cameras due now: rendered from the world as it is, in this thread (so
  // that lockstep and fast runs are reproducible), and published.
  void PublishCameras() {
    if (cameras->empty()) return;
    cameras->Due(world.time(), due);
    if (due.empty()) return;
    lights.resize(cars.size());
    for (std::size_t i = 0; i < cars.size(); ++i) {
      lights[i] = {cars[i]->headlights, cars[i]->indicators};
    }
    head_lamps.clear();
    {
      std::lock_guard lock(lamps_mutex);
      for (const auto& [id, state] : lamps) {
        head_lamps.push_back({id, state == 1, state == 2, state == 3});
      }
    }
    cameras->Snapshot(world, lights, head_lamps, traffic_looks);
    for (const std::size_t k : due) {
      // Each frame's noise from the seed, the camera and the frame's time.
      const auto stamp_ns = static_cast<std::uint64_t>(world.time().count());
      const std::uint64_t noise =
          seed * 0x9e3779b97f4a7c15ULL ^ (k + 1) * 0xbf58476d1ce4e5b9ULL ^ stamp_ns;
      if (!workers.empty()) {
        if (!workers[k]->Offer(noise, Stamp(world.time())) && workers[k]->dropped() % 100 == 1) {
          spdlog::warn("camera {}: {} frame(s) dropped: rendering is slower than the frame rate",
                       cameras->cameras()[k].name, workers[k]->dropped());
        }
        continue;
      }
      cameras->Render(k, image, noise);
      PublishImage(k, image, Stamp(world.time()));
    }
  }

  // Publishes camera k's frame (from the loop's thread, or the camera's worker).
  void PublishImage(std::size_t k, const Image& im, Time stamp) {
    const SimCamera& cam = cameras->cameras()[k];
    msg::Image m{};
    SetHeader(m.header, stamp, cam.frame_id.c_str());
    m.width = static_cast<std::uint32_t>(im.width_px);
    m.height = static_cast<std::uint32_t>(im.height_px);
    dds::BorrowString(m.encoding, "rgb8");
    m.is_bigendian = 0;
    m.step = 3 * m.width;
    auto& data = const_cast<std::vector<std::uint8_t>&>(im.rgb);
    dds::BorrowSequence(m.data, std::span<std::uint8_t>(data));
    camera_writers[k]->Write(m);
  }

  // One control period: commands, physics steps with their sensors and cameras, /clock,
  // ground truth.
  void Period() {
    TakeCommands();
    TakeLamps();
    TakeTraffic();
    ChooseLidarTraffic();
    for (std::int64_t k = 0; k < steps_per_period; ++k) {
      world.Step();
      NoteTrafficContacts();
      UpdateBoxes();
      for (std::size_t i = 0; i < cars.size(); ++i) {
        suites[i].Sample(world, world.Scene(), lidar_boxes[i], readings);
        Publish(i);
      }
      PublishCameras();
    }
    PublishState();
  }

  // Every car's ground truth, /clock, and the log's rows, for the world's time.
  void PublishState() {
    for (std::size_t i = 0; i < cars.size(); ++i) PublishGroundTruth(i);
    clock.Write(msg::Clock{dds::ToMsg(Stamp(world.time()))});
    if (log != nullptr) {
      for (std::size_t i = 0; i < cars.size(); ++i) {
        *log << cars[i]->name << ',';
        WriteReplayRow(*log, world.time(), world.State(static_cast<int>(i)));
      }
    }
  }

  // --- Lockstep ---------------------------------------------------------------------------

  // Announces the step at the world's time once every reader acknowledged its messages (the
  // protocol's rule 2); `last`: the simulator stops after it.
  void AnnounceStep(bool last) {
    for (const auto& car : cars) car->WaitForAcks(dds::kLockstepAckTimeout);
    for (std::size_t k = 0; k < camera_writers.size(); ++k) {
      if (!camera_writers[k]->WaitForAcks(dds::kLockstepAckTimeout)) {
        spdlog::warn("camera {}: a reader did not acknowledge its frame in time",
                     cameras->cameras()[k].name);
      }
    }
    if (last) {
      lockstep->End(Stamp(world.time()));
    } else {
      lockstep->Announce(Stamp(world.time()));
    }
  }
};

SimService::SimService(const dds::Participant& participant, const SimCity& city,
                       const maps::Map& map, const ServiceOptions& options)
    : impl_(std::make_unique<Impl>(participant, city, map, options)) {}

SimService::~SimService() = default;

void SimService::LogTo(std::ostream* out) {
  impl_->log = out;
  if (out != nullptr) *out << "vehicle," << kReplayLogHeader << '\n';
}

void SimService::Run(const std::atomic<bool>& stop) {
  Impl& s = *impl_;
  dds::LockstepServer* const lockstep = s.lockstep.get();
  if (lockstep != nullptr && !lockstep->WaitForControllers(stop)) return;
  const auto wall_start = std::chrono::steady_clock::now();
  const Duration sim_start = s.world.time();
  Duration last_report = sim_start;
  const auto duration_over = [&] {
    return s.options.duration && s.world.time() - sim_start >= *s.options.duration;
  };
  if (lockstep != nullptr) {
    s.PublishState();
    s.AnnounceStep(false);
  }
  while (!stop.load()) {
    if (duration_over()) break;
    if (lockstep != nullptr && !lockstep->WaitForAnswers(stop)) break;
    s.Period();
    if (lockstep != nullptr) s.AnnounceStep(stop.load() || duration_over());
    if (s.options.mode == SimMode::kRealTime) {
      const auto due = wall_start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                        (s.world.time() - sim_start) / s.options.real_time_factor);
      std::this_thread::sleep_until(due);
    }
    if (s.world.time() - last_report >= std::chrono::seconds(60)) {
      last_report = s.world.time();
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
      spdlog::info("simulated {:.0f} s in {:.0f} s of wall time ({:.1f}x)",
                   ToSeconds(s.world.time() - sim_start), wall,
                   ToSeconds(s.world.time() - sim_start) / wall);
    }
  }
  // Stopped while the controllers were deciding: the step announced is the last.
  if (lockstep != nullptr && !lockstep->ended()) lockstep->End(s.Stamp(s.world.time()));
}

std::map<SignalHeadId, LampState> SimService::Lamps() const {
  std::lock_guard lock(impl_->lamps_mutex);
  return impl_->lamps;
}

Duration SimService::time() const { return impl_->world.time(); }

std::int64_t SimService::traffic_collisions() const { return impl_->traffic_collisions.load(); }

std::int64_t SimService::steps() const { return impl_->world.steps(); }

}  // namespace autodrive::vehicle_sim
