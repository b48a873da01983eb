#pragma once
/// @file
/// The simulator service's DDS edge for its cars and the lamps (service.cpp): each car's devkit
/// topics (commands in; feedback, encoders, IPS, IMU, LIDAR and ground truth out) and the
/// lamp states of the city's signal heads. Messages become values here and nowhere else; the
/// rule of when a car is held for want of commands is `CommandWatch` (service_rules.h).

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"
#include "vehicle_sim/cameras.h"
#include "vehicle_sim/internal/service_rules.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/variability.h"
#include "vehicle_sim/vehicle.h"

namespace autodrive::vehicle_sim::internal {

/// One simulated car's DDS endpoints and what it was last told. Not copyable or movable (its
/// readers and writers are not). For the loop's thread only.
class CarEndpoints {
 public:
  /// Creates the car's readers and writers on `participant` (which must outlive it), and an
  /// `ips` writer more on each of `ips_participants` (a district's each);
  /// `command_noise`: what the car's actuators add to its commands.
  CarEndpoints(const dds::Participant& participant, VehicleId id, CommandNoise command_noise,
               const std::vector<const dds::Participant*>& ips_participants = {});
  CarEndpoints(const CarEndpoints&) = delete;
  CarEndpoints& operator=(const CarEndpoints&) = delete;

  /// Takes every command that arrived (non-finite throttle or steering ignored, the rest
  /// clamped to [-1, 1]) at simulated time `now`, and returns the command to apply: the newest,
  /// with the actuators' noise, throttle 0 while the car is held (`command_timeout` without
  /// a command; logged when it starts and ends).
  VehicleCommand TakeCommand(Duration now, Duration command_timeout);

  /// Publishes what the car's sensors read (`readings`; `imu`: the IMU's configuration, for
  /// the covariances); `origin`: the ROS time of simulated time 0. The position goes to the
  /// car's own `ips` topic and, with `ips_to` > 0, to the `ips_to`-th district's too.
  void Publish(const SensorReadings& readings, const ImuConfig& imu, Time origin,
               std::size_t ips_to = 0);

  /// Publishes the car's ground truth `state`, observed at `stamp`.
  void PublishGroundTruth(const VehicleState& state, Time stamp);

  /// Waits until every reader of every writer of the car acknowledged what it was sent
  /// (warns when one did not within `timeout`).
  void WaitForAcks(std::chrono::steady_clock::duration timeout) const;

  /// Its headlights and indicators as last commanded (for the cameras).
  [[nodiscard]] CarLights lights() const { return {headlights_, indicators_}; }
  /// `nigel_<n>`.
  [[nodiscard]] const std::string& name() const { return name_; }

 private:
  std::string name_;
  dds::Writer<msg::Float32> throttle_, steering_;
  dds::Writer<msg::JointState> left_encoder_, right_encoder_;
  std::vector<std::unique_ptr<dds::Writer<msg::Point>>> ips_;
  dds::Writer<msg::Imu> imu_;
  dds::Writer<msg::LaserScan> lidar_;
  dds::Writer<msg::TrackedVehicle> ground_truth_;
  dds::Reader<msg::Float32> throttle_command_, steering_command_;
  dds::Reader<msg::Int32> headlights_command_, indicators_command_;
  VehicleCommand command_;
  CommandNoise noise_;
  std::int32_t headlights_ = 0;
  std::int32_t indicators_ = 0;
  CommandWatch watch_;
};

/// What a light shows: 0 off, 1 red, 2 yellow, 3 green (the devkit's values).
using LampValue = std::int32_t;

/// The lamp states of the map's signal heads as last reported on `signal_<i>/state`.
/// Thread-safe: `Take` on the loop's thread, the others from any.
class SignalLamps {
 public:
  /// A reader per signal head of `map` on `participant_of(head)` (each must outlive it).
  SignalLamps(const std::function<const dds::Participant&(const maps::SignalHead&)>& participant_of,
              const maps::Map& map);
  SignalLamps(const SignalLamps&) = delete;
  SignalLamps& operator=(const SignalLamps&) = delete;

  /// Takes every state that arrived.
  void Take();
  /// Each head's lamp, as last reported (absent: none heard yet).
  [[nodiscard]] std::map<SignalHeadId, LampValue> Get() const;
  /// The lamps lit, for the cameras: `out` cleared, then one entry per head heard from.
  void Lit(std::vector<HeadLamps>& out) const;

 private:
  std::vector<std::pair<SignalHeadId, std::unique_ptr<dds::Reader<msg::Int32>>>> readers_;
  mutable std::mutex mutex_;
  std::map<SignalHeadId, LampValue> lamps_;
};

}  // namespace autodrive::vehicle_sim::internal
