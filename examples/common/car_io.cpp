#include "examples/common/car_io.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <thread>

#include "common/dds/conversions.h"
#include "common/dds/lockstep.h"
#include "common/dds/topics.h"

namespace autodrive::examples {

CarIo::CarIo(const dds::Participant& participant, VehicleId vehicle, PoseSource pose)
    : name_(VehicleName(vehicle)),
      source_(pose),
      ips_(participant, dds::topics::Ips(vehicle)),
      imu_(participant, dds::topics::Imu(vehicle)),
      lidar_(participant, dds::topics::Lidar(vehicle)),
      throttle_(participant, dds::topics::ThrottleCommand(vehicle)),
      steering_(participant, dds::topics::SteeringCommand(vehicle)) {
  if (pose == PoseSource::kEye) {
    eye_ = std::make_unique<dds::Reader<msg::FleetState>>(participant, dds::topics::EyeFleet());
  }
}

void CarIo::Take() {
  if (eye_) {
    // The Eye's newest pose of this car (its rear axle's middle, in the map frame).
    while (auto m = eye_->TakeOne()) {
      for (const auto& v : dds::Elements((*m)->vehicles)) {
        if (dds::View(v.vehicle_id) != name_) continue;
        const RigidTransform2 X = dds::FromMsg(v.pose.pose).ToRigidTransform2();
        position_ = X.translation();
        yaw_ = X.yaw();
      }
    }
  } else {
    while (auto m = ips_.TakeOne()) position_ = Eigen::Vector2d((*m)->x, (*m)->y);
    while (auto m = imu_.TakeOne()) {
      const auto& q = (*m)->orientation;
      yaw_ = YawFromQuaternion(Eigen::Quaterniond(q.w, q.x, q.y, q.z));
    }
  }
  while (auto m = lidar_.TakeOne()) {
    const auto& r = (*m)->ranges;
    scan_.assign(r._buffer, r._buffer + r._length);
    scan_stamp_ = dds::FromMsg((*m)->header.stamp);
    scan_increment_s_ = (*m)->time_increment;
  }
}

std::optional<RigidTransform2> CarIo::pose() const {
  if (!position_ || !yaw_) return std::nullopt;
  return RigidTransform2::FromXyYaw(position_->x(), position_->y(), *yaw_);
}

void CarIo::Command(double throttle, double steering) {
  throttle_.Write(msg::Float32{static_cast<float>(throttle)});
  steering_.Write(msg::Float32{static_cast<float>(steering)});
}

int CarIo::Run(const dds::Participant& participant, const std::string& lockstep, double rate_hz,
               const std::function<void(Time)>& decide, const std::atomic<bool>& stop) {
  if (lockstep.empty()) {
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(1.0 / rate_hz));
    auto next = std::chrono::steady_clock::now();
    while (!stop.load()) {
      decide(SystemNow());
      next += period;
      std::this_thread::sleep_until(next);
    }
    return 0;
  }
  dds::LockstepClient client(participant, lockstep);
  if (!client.WaitForSimulator(stop)) return 0;
  if (!throttle_.WaitForReaders(1, std::chrono::seconds(5)) ||
      !steering_.WaitForReaders(1, std::chrono::seconds(5))) {
    spdlog::warn("lockstep: the simulator does not read {}'s commands", name_);
  }
  if (!client.Register(stop)) return 0;
  for (;;) {
    std::optional<Time> t;
    try {
      t = client.NextStep(stop);
    } catch (const dds::LockstepError&) {
      if (stop.load()) break;  // told to stop as the run ended: the simulator went first
      throw;
    }
    if (!t) break;
    decide(*t);
    if (!throttle_.WaitForAcks(dds::kLockstepAckTimeout) ||
        !steering_.WaitForAcks(dds::kLockstepAckTimeout)) {
      spdlog::warn("lockstep: {}'s commands were not acknowledged in time", name_);
    }
    client.Answer();
  }
  return 0;
}

}  // namespace autodrive::examples
