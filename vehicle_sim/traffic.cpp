#include "vehicle_sim/traffic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "common/dds/message.h"

namespace autodrive::vehicle_sim {

namespace {

// Our classes carry the wire values of the IDL constants.
static_assert(static_cast<int>(TrafficClass::kCar) ==
              autodrive_msgs_msg_TrafficObject_Constants_CAR);
static_assert(static_cast<int>(TrafficClass::kBus) ==
              autodrive_msgs_msg_TrafficObject_Constants_BUS);
static_assert(static_cast<int>(TrafficClass::kTruck) ==
              autodrive_msgs_msg_TrafficObject_Constants_TRUCK);
static_assert(static_cast<int>(TrafficClass::kMotorcycle) ==
              autodrive_msgs_msg_TrafficObject_Constants_MOTORCYCLE);
static_assert(static_cast<int>(TrafficClass::kBicycle) ==
              autodrive_msgs_msg_TrafficObject_Constants_BICYCLE);
static_assert(static_cast<int>(TrafficClass::kPedestrian) ==
              autodrive_msgs_msg_TrafficObject_Constants_PEDESTRIAN);
static_assert(static_cast<int>(TrafficClass::kEmergency) ==
              autodrive_msgs_msg_TrafficObject_Constants_EMERGENCY);

// The signals' bits (TrafficObject.idl: bit 0 left, 1 right, 2 brake).
constexpr std::uint8_t kLeftBit = 1;
constexpr std::uint8_t kRightBit = 2;
constexpr std::uint8_t kBrakeBit = 4;

TrafficClass ClassFromWire(std::uint8_t wire) {
  return wire >= static_cast<std::uint8_t>(TrafficClass::kCar) &&
                 wire <= static_cast<std::uint8_t>(TrafficClass::kEmergency)
             ? static_cast<TrafficClass>(wire)
             : TrafficClass::kUnknown;
}

bool Finite(double v) { return std::isfinite(v); }

// Why object `o` cannot be used, or empty (the text is only built for a bad object).
std::string Problem(const autodrive_msgs_msg_dds__TrafficObject_& o) {
  const auto& p = o.pose.position;
  const auto& q = o.pose.orientation;
  const auto edge_ok = [](double e) { return e > 0 && e <= kMaxTrafficSizeM; };
  const bool position_ok =
      Finite(p.x) && Finite(p.y) && Finite(p.z) &&
      std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}) <= kMaxTrafficCoordinateM;
  const bool rotation_ok = Finite(q.x) && Finite(q.y) && Finite(q.z) && Finite(q.w) &&
                           q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w >= 1e-12;
  const bool size_ok = edge_ok(o.size.x) && edge_ok(o.size.y) && edge_ok(o.size.z);
  const bool speed_ok = std::abs(o.speed_mps) <= kMaxTrafficSpeedMps;  // false for NaN
  const std::size_t id_length = dds::View(o.object_id).size();
  if (position_ok && rotation_ok && size_ok && speed_ok && id_length <= kMaxTrafficIdLength) {
    return {};
  }
  std::ostringstream why;
  if (!position_ok) {
    why << "position (" << p.x << ", " << p.y << ", " << p.z << ") is not finite or beyond "
        << kMaxTrafficCoordinateM << " m";
  } else if (!rotation_ok) {
    why << "orientation (" << q.x << ", " << q.y << ", " << q.z << ", " << q.w
        << ") is not a rotation";
  } else if (!size_ok) {
    why << "size (" << o.size.x << ", " << o.size.y << ", " << o.size.z << ") m is outside (0, "
        << kMaxTrafficSizeM << "]";
  } else if (!speed_ok) {
    why << "speed " << o.speed_mps << " m/s is not finite or beyond " << kMaxTrafficSpeedMps;
  } else {
    why << "its id has " << id_length << " characters, more than " << kMaxTrafficIdLength;
  }
  return why.str();
}

// FNV-1a, 64 bits: a hash that is the same on every machine and standard library.
std::uint64_t Fnv1a(std::string_view text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

std::string_view ToString(TrafficClass c) {
  switch (c) {
    case TrafficClass::kUnknown:
      return "unknown";
    case TrafficClass::kCar:
      return "car";
    case TrafficClass::kBus:
      return "bus";
    case TrafficClass::kTruck:
      return "truck";
    case TrafficClass::kMotorcycle:
      return "motorcycle";
    case TrafficClass::kBicycle:
      return "bicycle";
    case TrafficClass::kPedestrian:
      return "pedestrian";
    case TrafficClass::kEmergency:
      return "emergency";
  }
  return "unknown";
}

TrafficReadReport ReadTrafficObjects(const msg::TrafficObjects& message,
                                     std::vector<TrafficObject>& objects) {
  TrafficReadReport report;
  const auto in = dds::Elements(message.objects);
  const std::size_t n = std::min(in.size(), kMaxTrafficObjects);
  if (in.size() > n) {
    report.skipped += in.size() - n;
    std::ostringstream why;
    why << in.size() << " objects: only the first " << kMaxTrafficObjects << " are taken";
    report.first_problem = why.str();
  }
  // Elements are overwritten in place (their strings keep their buffers); the vector only
  // shrinks at the end.
  std::size_t used = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto& o = in[i];
    const std::string problem = Problem(o);
    if (!problem.empty()) {
      if (report.first_problem.empty()) {
        report.first_problem = "object " + std::to_string(i) + " ('" +
                               std::string(dds::View(o.object_id).substr(0, 40)) + "'): " + problem;
      }
      ++report.skipped;
      continue;
    }
    if (used == objects.size()) objects.emplace_back();
    TrafficObject& t = objects[used++];
    t.id.assign(dds::View(o.object_id));
    t.object_class = ClassFromWire(o.object_class);
    const auto& q = o.pose.orientation;
    t.X_MO = Eigen::Translation3d(o.pose.position.x, o.pose.position.y, o.pose.position.z) *
             Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized();
    t.size_m = {o.size.x, o.size.y, o.size.z};
    t.speed_mps = o.speed_mps;
    t.left_indicator = (o.signals & kLeftBit) != 0;
    t.right_indicator = (o.signals & kRightBit) != 0;
    t.brake = (o.signals & kBrakeBit) != 0;
  }
  objects.resize(used);
  return report;
}

Duration TrafficExtrapolation(Time stamp, Time now) {
  return std::clamp(now - stamp, Duration{0}, kMaxTrafficExtrapolation);
}

Eigen::Isometry3d TrafficPoseAfter(const TrafficObject& object, Duration dt) {
  Eigen::Isometry3d X_MO = object.X_MO;
  X_MO.translation() += object.X_MO.linear().col(0) * (object.speed_mps * ToSeconds(dt));
  return X_MO;
}

DynamicBox TrafficBox(const TrafficObject& object, const Eigen::Isometry3d& X_MO, BoxId id) {
  DynamicBox box{id, X_MO, object.size_m / 2};
  box.X_MB.translation() = X_MO * Eigen::Vector3d(0, 0, object.size_m.z() / 2);
  return box;
}

TrafficPaint TrafficPaintOf(TrafficClass object_class, std::string_view id) {
  switch (object_class) {
    case TrafficClass::kBus:
      return {{240, 190, 20}, {240, 190, 20}};
    case TrafficClass::kTruck:
      return {{70, 100, 150}, {70, 100, 150}};
    case TrafficClass::kEmergency:
      return {{240, 240, 240}, {210, 25, 25}};
    case TrafficClass::kMotorcycle:
      return {{35, 35, 40}, {35, 35, 40}};
    case TrafficClass::kBicycle:
      return {{40, 140, 60}, {40, 140, 60}};
    case TrafficClass::kPedestrian:
      return {{60, 80, 200}, {60, 80, 200}};
    case TrafficClass::kUnknown:
    case TrafficClass::kCar:
      break;
  }
  static constexpr std::array<Rgb, 6> kCars{Rgb{235, 235, 235}, Rgb{220, 217, 208},
                                            Rgb{190, 191, 196}, Rgb{140, 141, 146},
                                            Rgb{90, 91, 96},    Rgb{55, 56, 60}};
  const Rgb c = kCars[Fnv1a(id) % kCars.size()];
  return {c, c};
}

RenderTraffic TrafficLook(const TrafficObject& object, const Eigen::Isometry3d& X_MO) {
  RenderTraffic r;
  r.X_MO = X_MO;
  r.size_m = object.size_m;
  r.speed_mps = object.speed_mps;
  switch (object.object_class) {
    case TrafficClass::kBus:
    case TrafficClass::kTruck:
      r.shape = TrafficShape::kTall;
      break;
    case TrafficClass::kMotorcycle:
    case TrafficClass::kBicycle:
    case TrafficClass::kPedestrian:
      r.shape = TrafficShape::kBlock;
      break;
    case TrafficClass::kUnknown:
    case TrafficClass::kCar:
    case TrafficClass::kEmergency:
      r.shape = TrafficShape::kCar;
      break;
  }
  const TrafficPaint paint = TrafficPaintOf(object.object_class, object.id);
  r.body = paint.body;
  r.roof = paint.roof;
  r.brake = object.brake;
  r.left_indicator = object.left_indicator;
  r.right_indicator = object.right_indicator;
  return r;
}

}  // namespace autodrive::vehicle_sim
