#include "vehicle_sim/internal/car_endpoints.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <span>

#include "common/aspect.h"
#include "common/dds/conversions.h"
#include "common/dds/topics.h"

namespace autodrive::vehicle_sim::internal {

namespace {

namespace topics = dds::topics;

void SetHeader(std_msgs_msg_dds__Header_& header, Time stamp, const char* frame) {
  header.stamp = dds::ToMsg(stamp);
  dds::BorrowString(header.frame_id, frame);
}

}  // namespace

CarEndpoints::CarEndpoints(const dds::Participant& p, VehicleId id, CommandNoise command_noise,
                           const std::vector<const dds::Participant*>& ips_participants)
    : name_(VehicleName(id)),
      throttle_(p, topics::Throttle(id)),
      steering_(p, topics::Steering(id)),
      left_encoder_(p, topics::LeftEncoder(id)),
      right_encoder_(p, topics::RightEncoder(id)),
      imu_(p, topics::Imu(id)),
      lidar_(p, topics::Lidar(id)),
      ground_truth_(p, topics::GroundTruth(id)),
      throttle_command_(p, topics::ThrottleCommand(id)),
      steering_command_(p, topics::SteeringCommand(id)),
      headlights_command_(p, topics::HeadlightsCommand(id)),
      indicators_command_(p, topics::IndicatorsCommand(id)),
      noise_(std::move(command_noise)) {
  ips_.push_back(std::make_unique<dds::Writer<msg::Point>>(p, topics::Ips(id)));
  for (const dds::Participant* district : ips_participants) {
    ips_.push_back(std::make_unique<dds::Writer<msg::Point>>(*district, topics::Ips(id)));
  }
}

VehicleCommand CarEndpoints::TakeCommand(Duration now, Duration command_timeout) {
  bool fresh = false;
  while (auto m = throttle_command_.TakeOne()) {
    if (std::isfinite((*m)->data)) {
      command_.throttle = std::clamp(static_cast<double>((*m)->data), -1.0, 1.0);
      fresh = true;
    }
  }
  while (auto m = steering_command_.TakeOne()) {
    if (std::isfinite((*m)->data)) {
      command_.steering = std::clamp(static_cast<double>((*m)->data), -1.0, 1.0);
      fresh = true;
    }
  }
  while (auto m = headlights_command_.TakeOne()) headlights_ = (*m)->data;
  while (auto m = indicators_command_.TakeOne()) indicators_ = (*m)->data;
  switch (watch_.Update(fresh, now, command_timeout)) {
    case CommandWatch::Change::kResumed:
      spdlog::info("{}: commands again", name_);
      break;
    case CommandWatch::Change::kTimedOut:
      spdlog::warn("{}: no command for {:.3f} s: holding still", name_, ToSeconds(command_timeout));
      break;
    case CommandWatch::Change::kNone:
      break;
  }
  VehicleCommand applied = noise_.Apply(command_);
  if (watch_.timed_out()) applied.throttle = 0.0;
  return applied;
}

void CarEndpoints::Publish(const SensorReadings& r, const ImuConfig& c, Time origin,
                           std::size_t ips_to) {
  if (r.feedback) {
    throttle_.Write(msg::Float32{static_cast<float>(r.feedback->throttle)});
    steering_.Write(msg::Float32{static_cast<float>(r.feedback->steering_rad)});
  }
  if (r.encoders) {
    for (int k = 0; k < 2; ++k) {
      const char* frame = k == 0 ? "left_encoder" : "right_encoder";
      msg::JointState js{};
      SetHeader(js.header, origin + r.encoders->stamp, frame);
      char* names[1] = {const_cast<char*>(frame)};
      dds::BorrowSequence(js.name, std::span<char*>(names, 1));
      double position[1] = {r.encoders->angle_rad[static_cast<std::size_t>(k)]};
      dds::BorrowSequence(js.position, std::span<double>(position, 1));
      (k == 0 ? left_encoder_ : right_encoder_).Write(js);
    }
  }
  if (r.ips) {
    const Eigen::Vector3d& p = r.ips->position_m;
    // geometry_msgs/Point has no header: the source timestamp says when the position was
    // taken (the SCM observes it then), however late a loaded simulator publishes it.
    const msg::Point point{p.x(), p.y(), p.z()};
    ips_[0]->WriteAt(point, origin + r.ips->stamp);
    if (ips_to > 0) ips_.at(ips_to)->WriteAt(point, origin + r.ips->stamp);
  }
  if (r.imu) {
    msg::Imu m{};
    SetHeader(m.header, origin + r.imu->stamp, "imu");
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
    imu_.Write(m);
  }
  if (r.lidar) {
    const LidarScan& s = *r.lidar;
    msg::LaserScan m{};
    SetHeader(m.header, origin + s.stamp, "lidar");
    m.angle_min = static_cast<float>(s.angle_min_rad);
    m.angle_increment = static_cast<float>(s.angle_increment_rad);
    m.angle_max = static_cast<float>(s.angle_min_rad + (static_cast<double>(s.ranges.size()) - 1) *
                                                           s.angle_increment_rad);
    m.time_increment = static_cast<float>(s.time_increment_s);
    m.scan_time = static_cast<float>(s.scan_time_s);
    m.range_min = static_cast<float>(s.range_min_m);
    m.range_max = static_cast<float>(s.range_max_m);
    auto& ranges = const_cast<std::vector<float>&>(s.ranges);
    dds::BorrowSequence(m.ranges, std::span<float>(ranges));
    lidar_.Write(m);
  }
}

void CarEndpoints::PublishGroundTruth(const VehicleState& s, Time stamp) {
  msg::TrackedVehicle m{};
  dds::BorrowString(m.vehicle_id, name_.c_str());
  m.source = autodrive_msgs_msg_TrackedVehicle_Constants_SIM_GROUND_TRUTH;
  m.observed = dds::ToMsg(stamp);
  m.pose.pose = dds::ToMsg(s.X_MV);
  m.twist.twist.linear = {s.v_V_mps.x(), s.v_V_mps.y(), s.v_V_mps.z()};
  m.twist.twist.angular = {s.w_V_radps.x(), s.w_V_radps.y(), s.w_V_radps.z()};
  dds::BorrowString(m.map_lane_id, "");
  ground_truth_.Write(m);
}

void CarEndpoints::WaitForAcks(std::chrono::steady_clock::duration timeout) const {
  const bool ok =
      throttle_.WaitForAcks(timeout) && steering_.WaitForAcks(timeout) &&
      left_encoder_.WaitForAcks(timeout) && right_encoder_.WaitForAcks(timeout) &&
      std::ranges::all_of(ips_, [&](const auto& w) { return w->WaitForAcks(timeout); }) &&
      imu_.WaitForAcks(timeout) && lidar_.WaitForAcks(timeout) &&
      ground_truth_.WaitForAcks(timeout);
  if (!ok) spdlog::warn("{}: a reader did not acknowledge its data in time", name_);
}

SignalLamps::SignalLamps(
    const std::function<const dds::Participant&(const maps::SignalHead&)>& participant_of,
    const maps::Map& map) {
  for (const maps::SignalHead& head : map.signal_heads) {
    readers_.emplace_back(head.id, std::make_unique<dds::Reader<msg::Int32>>(
                                       participant_of(head), topics::SignalState(head.id)));
  }
}

void SignalLamps::Take() {
  std::lock_guard lock(mutex_);
  for (auto& [id, reader] : readers_) {
    while (auto m = reader->TakeOne()) lamps_[id] = (*m)->data;
  }
}

std::map<SignalHeadId, LampValue> SignalLamps::Get() const {
  std::lock_guard lock(mutex_);
  return lamps_;
}

void SignalLamps::Lit(std::vector<HeadLamps>& out) const {
  out.clear();
  std::lock_guard lock(mutex_);
  for (const auto& [id, state] : lamps_) {
    const std::optional<Aspect> shown = AspectFromWire(state);
    out.push_back({id, shown == Aspect::kRed, shown == Aspect::kYellow, shown == Aspect::kGreen});
  }
}

}  // namespace autodrive::vehicle_sim::internal
