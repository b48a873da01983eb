#pragma once
/// @file
/// Where the fleet registry's observations come from. Each source takes what arrived on its
/// topics and records it: the devkit's `ips` topics, the Eye's poses, and SUMO's background
/// traffic.

#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/geometry.h"
#include "common/ids.h"
#include "common/time.h"
#include "scm/core/fleet.h"

namespace autodrive::scm {

/// A source of vehicle observations. Polled by the daemon's loop: never blocks.
class ObservationSource {
 public:
  ObservationSource() = default;
  ObservationSource(const ObservationSource&) = delete;
  ObservationSource& operator=(const ObservationSource&) = delete;
  virtual ~ObservationSource() = default;

  /// Takes what arrived and records it in `fleet`. `now` stamps what carries no time of its
  /// own. Returns how many observations were recorded.
  virtual std::size_t Poll(const ClockReading& now, FleetRegistry& fleet) = 0;
  /// "ips", "eye", ...
  [[nodiscard]] virtual std::string_view name() const = 0;
  /// Samples (or objects of a sample) refused as malformed (not finite, out of range).
  [[nodiscard]] virtual std::uint64_t malformed() const = 0;
};

/// Position from the devkit's `/autodrive/nigel_<n>/ips` (geometry_msgs/Point, map frame): the
/// simulator's ground truth in simulation, the lab's positioning system on the real track.
/// A position only: the heading is estimated from the motion (once the car moved more than
/// `kMinMotion_m`); until then it is unknown and the registry locates the car by position alone.
/// Observations are labelled `PoseSource::kIps`. The message carries no time: on the wall clock
/// each is stamped when its writer wrote it (the sample's source timestamp, which the simulator
/// and a lab's positioning system write as they measure), unless that is in the future or older
/// than `kMaxWriterAge` (the hosts' clocks disagree), when it is stamped on arrival, as it always
/// is on a simulated clock (whose time the writer's stamp is not in).
class IpsSource final : public ObservationSource {
 public:
  /// Motion needed before a heading is estimated from two positions.
  static constexpr double kMinMotion_m = 0.01;
  /// The oldest writer's stamp taken as the time of a position (older: clocks disagree).
  static constexpr Duration kMaxWriterAge = std::chrono::seconds(1);

  IpsSource(const dds::Participant& participant, const std::vector<VehicleId>& vehicles,
            ClockKind clock);
  std::size_t Poll(const ClockReading& now, FleetRegistry& fleet) override;
  [[nodiscard]] std::string_view name() const override { return "ips"; }
  [[nodiscard]] std::uint64_t malformed() const override { return malformed_; }

 private:
  struct Track {
    VehicleId vehicle{0};
    std::unique_ptr<dds::Reader<msg::Point>> reader;
    std::optional<Eigen::Vector2d> last;  ///< the last position, once one came
    std::optional<double> yaw_rad;        ///< from the motion, once it moved
  };
  std::vector<Track> tracks_;
  ClockKind clock_;
  dds::Message<msg::Point> sample_;
  dds::SampleInfo info_;
  std::uint64_t malformed_ = 0;
};

/// The Eye's poses from `/autodrive/eye/fleet` (autodrive-eye run): each car's origin and
/// heading, speed and covariance at its frame's exposure time, labelled `PoseSource::kEye`.
/// Samples with a malformed name or a value that is not finite are refused and counted.
class EyeSource final : public ObservationSource {
 public:
  explicit EyeSource(const dds::Participant& participant);
  std::size_t Poll(const ClockReading& now, FleetRegistry& fleet) override;
  [[nodiscard]] std::string_view name() const override { return "eye"; }
  [[nodiscard]] std::uint64_t malformed() const override { return malformed_; }

 private:
  dds::Reader<msg::FleetState> reader_;
  dds::Message<msg::FleetState> sample_;
  std::uint64_t malformed_ = 0;
};

/// The background traffic from `/autodrive/scm/traffic` (autodrive-traffic: SUMO's vehicles,
/// thousands per message at 10-20 Hz), recorded with `FleetRegistry::ObserveTraffic` at the
/// message's stamp. Keeps the newest message only (keep-last 1): a loop that falls behind skips
/// to it. Objects refused by the registry (see there) are counted as malformed. Steady state
/// (the same vehicles again) allocates nothing: the message and the batch keep their memory.
class TrafficSource final : public ObservationSource {
 public:
  explicit TrafficSource(const dds::Participant& participant);
  std::size_t Poll(const ClockReading& now, FleetRegistry& fleet) override;
  [[nodiscard]] std::string_view name() const override { return "traffic"; }
  [[nodiscard]] std::uint64_t malformed() const override { return malformed_; }

 private:
  dds::Reader<msg::TrafficObjects> reader_;
  dds::Message<msg::TrafficObjects> sample_;
  std::vector<TrafficObservation> batch_;
  std::uint64_t malformed_ = 0;
};

}  // namespace autodrive::scm
