#include "vehicle_sim/service.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

namespace {

namespace topics = dds::topics;

void SetHeader(std_msgs_msg_dds__Header_& header, Time stamp, const char* frame) {
  header.stamp = dds::ToMsg(stamp);
  dds::BorrowString(header.frame_id, frame);
}

// One car's DDS endpoints and what it was last told.
struct CarEndpoints {
  CarEndpoints(const dds::Participant& p, VehicleId id)
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
        indicators_command(p, topics::IndicatorsCommand(id)) {}

  std::string name;
  dds::Writer<msg::Float32> throttle, steering;
  dds::Writer<msg::JointState> left_encoder, right_encoder;
  dds::Writer<msg::Point> ips;
  dds::Writer<msg::Imu> imu;
  dds::Writer<msg::LaserScan> lidar;
  dds::Writer<msg::TrackedVehicle> ground_truth;
  dds::Reader<msg::Float32> throttle_command, steering_command;
  dds::Reader<msg::Int32> headlights_command, indicators_command;

  VehicleCommand command;
  std::int32_t headlights = 0;
  std::int32_t indicators = 0;
  Duration last_command{0};
  bool timed_out = false;
  bool ever_commanded = false;
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
  std::vector<DynamicBox> boxes;
  SensorReadings readings;

  Impl(const dds::Participant& participant, const SimCity& city, const maps::Map& map,
       const ServiceOptions& o)
      : options(o),
        world(map, city.sim.world),
        cars_config(city.sim.vehicles),
        clock(participant, topics::Clock()) {
    AUTODRIVE_THROW_UNLESS(o.control_period >= world.options().step,
                           "the control period " << ToSeconds(o.control_period)
                                                 << " s is shorter than the physics step "
                                                 << ToSeconds(world.options().step) << " s");
    AUTODRIVE_THROW_UNLESS(o.real_time_factor > 0 && std::isfinite(o.real_time_factor),
                           "the real-time factor must be positive, got " << o.real_time_factor);
    steps_per_period = o.control_period / world.options().step;
    const std::vector<RigidTransform2> poses = SpawnPoses(city.sim, map);
    for (std::size_t i = 0; i < cars_config.size(); ++i) {
      const SimVehicleConfig& c = cars_config[i];
      const int index = world.AddVehicle(c.params, poses[i]);
      suites.emplace_back(c.sensors, index, city.sim.seed);
      cars.push_back(std::make_unique<CarEndpoints>(participant, ParseVehicleName(c.name)));
    }
    for (const maps::SignalHead& head : map.signal_heads) {
      lamp_readers.emplace_back(head.id, std::make_unique<dds::Reader<msg::Int32>>(
                                             participant, topics::SignalState(head.id)));
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
      VehicleCommand applied = car.command;
      if (car.timed_out) applied.throttle = 0.0;
      world.SetCommand(static_cast<int>(i), applied);
    }
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

  // One control period: commands, physics steps with their sensors, /clock, ground truth.
  void Period() {
    TakeCommands();
    TakeLamps();
    for (std::int64_t k = 0; k < steps_per_period; ++k) {
      world.Step();
      VehicleBoxes(world, boxes);
      for (std::size_t i = 0; i < cars.size(); ++i) {
        suites[i].Sample(world, world.Scene(), boxes, readings);
        Publish(i);
      }
    }
    for (std::size_t i = 0; i < cars.size(); ++i) PublishGroundTruth(i);
    clock.Write(msg::Clock{dds::ToMsg(Stamp(world.time()))});
  }
};

SimService::SimService(const dds::Participant& participant, const SimCity& city,
                       const maps::Map& map, const ServiceOptions& options)
    : impl_(std::make_unique<Impl>(participant, city, map, options)) {}

SimService::~SimService() = default;

void SimService::Run(const std::atomic<bool>& stop) {
  Impl& s = *impl_;
  const auto wall_start = std::chrono::steady_clock::now();
  const Duration sim_start = s.world.time();
  Duration last_report = sim_start;
  while (!stop.load()) {
    if (s.options.duration && s.world.time() - sim_start >= *s.options.duration) break;
    s.Period();
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
}

std::map<SignalHeadId, LampState> SimService::Lamps() const {
  std::lock_guard lock(impl_->lamps_mutex);
  return impl_->lamps;
}

Duration SimService::time() const { return impl_->world.time(); }

std::int64_t SimService::steps() const { return impl_->world.steps(); }

}  // namespace autodrive::vehicle_sim
