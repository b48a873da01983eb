#pragma once
/// @file
/// Background traffic in the simulated world: SUMO's vehicles as `autodrive-traffic` publishes
/// them on `/autodrive/scm/traffic` (autodrive_msgs/TrafficObjects). The DDS service reads the
/// newest message once per control period, where it reads the cars' commands, and puts every
/// object in the world as a box of its size standing on the ground at its pose:
/// - the LIDARs see it (`TrafficBox`, a `DynamicBox` like the other cars');
/// - the cars collide with it (`World::SetTraffic`: a fixed obstacle of infinite mass, moved to
///   its new pose each period; a car that drives into it stops against it and does not push it);
/// - the cameras draw it (`TrafficLook`: a car body of its size in its class's colour, with
///   brake lights and indicators).
/// See docs/vehicle_sim.md, "Background traffic".
///
/// Frames and units: the map frame M (x east, y north, z up), metres, seconds. An object's frame
/// O has its origin at the centre of its footprint on the ground, x forward, z up.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/dds/messages.h"
#include "common/time.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/renderer.h"

namespace autodrive::vehicle_sim {

/// What a background object is (autodrive_msgs/TrafficObject's `object_class`; the numbers are
/// the wire's, checked where they are read). A number the message type does not define reads as
/// `kUnknown` and is drawn as a car.
enum class TrafficClass : std::uint8_t {
  kUnknown = 0,
  kCar = 1,
  kBus = 2,
  kTruck = 3,
  kMotorcycle = 4,
  kBicycle = 5,
  kPedestrian = 6,
  kEmergency = 7,
};
/// "car", "bus", ... ("unknown").
[[nodiscard]] std::string_view ToString(TrafficClass c);

/// One background object as the newest message gave it.
struct TrafficObject {
  std::string id;  ///< SUMO's id
  TrafficClass object_class = TrafficClass::kCar;
  /// Frame O in the map frame: the centre of the footprint on the ground, x forward, z up, at
  /// the message's stamp.
  Eigen::Isometry3d X_MO = Eigen::Isometry3d::Identity();
  /// Length (along O's x), width and height, metres; each in (0, kMaxTrafficSizeM].
  Eigen::Vector3d size_m{0.32, 0.13, 0.11};
  double speed_mps = 0.0;  ///< along O's x (lab metres per second)
  bool left_indicator = false;
  bool right_indicator = false;
  bool brake = false;
};

/// At most this many objects of a message are taken (the rest are skipped, counted): what
/// arrives from the network never grows without bound. A city of thousands fits.
inline constexpr std::size_t kMaxTrafficObjects = 20000;
/// The largest edge an object may have (m): a check of units, not of realism (a 1:14 bus is
/// about 0.9 m long).
inline constexpr double kMaxTrafficSizeM = 20.0;
/// Coordinates beyond this (m) are refused: no lab is that large, and ODE loses precision.
inline constexpr double kMaxTrafficCoordinateM = 1e4;
/// Speeds beyond this (m/s) are refused.
inline constexpr double kMaxTrafficSpeedMps = 100.0;
/// Ids longer than this are refused (SUMO's are a few characters).
inline constexpr std::size_t kMaxTrafficIdLength = 256;
/// In real-time mode an object is moved along its heading by its speed times the message's
/// age, at most this long.
inline constexpr Duration kMaxTrafficExtrapolation = std::chrono::milliseconds(200);

/// What `ReadTrafficObjects` could not use.
struct TrafficReadReport {
  std::size_t skipped = 0;    ///< objects left out (a bad field, or beyond kMaxTrafficObjects)
  std::string first_problem;  ///< the first one's reason, naming the object and the value
};

/// Reads the objects of `message` into `objects`, in the message's order, reusing the storage
/// of its elements (no allocation in steady state while the ids stay within the string's
/// small-size buffer). An object with a non-finite position, orientation, size or speed, a
/// quaternion of norm below 1e-6, an edge outside (0, kMaxTrafficSizeM], a coordinate beyond
/// kMaxTrafficCoordinateM, a speed beyond kMaxTrafficSpeedMps or an id longer than
/// kMaxTrafficIdLength is skipped and reported, never thrown: the message comes from the
/// network. Orientations are normalised. Ids are not
/// checked for uniqueness (two objects with one id are two bodies).
TrafficReadReport ReadTrafficObjects(const msg::TrafficObjects& message,
                                     std::vector<TrafficObject>& objects);

/// How long to extrapolate an object in real-time mode: `now - stamp`, clamped to
/// [0, kMaxTrafficExtrapolation] (a message stamped in the future is taken as it is).
[[nodiscard]] Duration TrafficExtrapolation(Time stamp, Time now);

/// The object's frame O `dt` after its message's stamp: moved by speed x dt along O's x axis.
[[nodiscard]] Eigen::Isometry3d TrafficPoseAfter(const TrafficObject& object, Duration dt);

/// The object's box as the LIDARs and the physics see it, at `X_MO`: from the ground (O's
/// origin) to its height, its length along O's x and its width along O's y.
[[nodiscard]] DynamicBox TrafficBox(const TrafficObject& object, const Eigen::Isometry3d& X_MO,
                                    BoxId id);

/// The colours an object is drawn in: `body`, and `roof` (a car's cabin, the top an overhead
/// camera sees). Deterministic: a car is one of six whites and greys chosen by a hash of its
/// id (FNV-1a, the same on every machine); a bus yellow; a truck steel blue; an emergency
/// vehicle white with a red roof; a motorcycle black, a bicycle green, a pedestrian blue; an
/// unknown class is drawn as a car.
struct TrafficPaint {
  Rgb body;
  Rgb roof;
};
[[nodiscard]] TrafficPaint TrafficPaintOf(TrafficClass object_class, std::string_view id);

/// The object as the cameras draw it at `X_MO` (its shape from its class, `TrafficPaintOf`'s
/// colours, its lights from its signals).
[[nodiscard]] RenderTraffic TrafficLook(const TrafficObject& object, const Eigen::Isometry3d& X_MO);

}  // namespace autodrive::vehicle_sim
