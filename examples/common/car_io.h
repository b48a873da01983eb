#pragma once
/// @file
/// One car's public topics as an example agent uses them: its pose (from its devkit `ips` and
/// `imu`, or from the Eye's fleet), its LIDAR scan, its throttle and steering commands; and the
/// loop that calls the agent's decision once per simulated step (the simulator's lockstep, as
/// the scenario runner starts agents) or at a rate on the wall clock (a real car).

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/writer.h"
#include "common/geometry.h"
#include "common/ids.h"
#include "common/time.h"

namespace autodrive::examples {

enum class PoseSource { kIps, kEye };

class CarIo {
 public:
  CarIo(const dds::Participant& participant, VehicleId vehicle, PoseSource pose);

  /// Takes what arrived: the newest pose and scan. Call it at every decision.
  void Take();
  /// The car's rear-axle pose in the map frame, once one came.
  [[nodiscard]] std::optional<RigidTransform2> pose() const;
  /// The newest LIDAR scan (beam i at i degrees counter-clockwise from the front), empty before.
  [[nodiscard]] std::span<const float> scan() const { return scan_; }
  /// When the newest scan's first beam was taken, and the time between two beams (s; 0 for a
  /// scan taken at once): a rotating LIDAR takes its beams as the car moves.
  [[nodiscard]] Time scan_stamp() const { return scan_stamp_; }
  [[nodiscard]] double scan_increment_s() const { return scan_increment_s_; }
  /// Writes the commands (normalised, as the devkit's topics carry them).
  void Command(double throttle, double steering);

  /// Calls `decide(now)` (`now` the system time) once per step of the simulator's lockstep as
  /// controller `lockstep`, or, when that is empty, `rate_hz` times a second on the wall clock;
  /// until `stop` is set or the lockstep ends. Returns the exit code.
  int Run(const dds::Participant& participant, const std::string& lockstep, double rate_hz,
          const std::function<void(Time)>& decide, const std::atomic<bool>& stop);

 private:
  std::string name_;
  PoseSource source_;
  dds::Reader<msg::Point> ips_;
  dds::Reader<msg::Imu> imu_;
  std::unique_ptr<dds::Reader<msg::FleetState>> eye_;
  dds::Reader<msg::LaserScan> lidar_;
  dds::Writer<msg::Float32> throttle_, steering_;
  std::optional<Eigen::Vector2d> position_;
  std::optional<double> yaw_;
  std::vector<float> scan_;
  Time scan_stamp_{};
  double scan_increment_s_ = 0.0;
};

}  // namespace autodrive::examples
