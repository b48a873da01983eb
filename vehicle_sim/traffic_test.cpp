// Background traffic: the message read strictly, the objects' poses, boxes and colours; a car
// stops against a background box in the physics; the LIDAR sees the same with thousands of
// boxes as every beam testing every box; the cameras draw an object in view in its colour and
// build nothing for thousands out of view. The DDS service's traffic is in service_test.cpp.
#include "vehicle_sim/traffic.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "common/camera/camera_model.h"
#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "vehicle_sim/sensors.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {
namespace {

using std::chrono::milliseconds;
using testing::HasSubstr;

struct Spec {
  std::string id;
  std::uint8_t object_class = autodrive_msgs_msg_TrafficObject_Constants_CAR;
  double x = 0, y = 0, yaw = 0;
  Eigen::Vector3d size{0.32, 0.13, 0.11};
  double speed = 0;
  std::uint8_t signals = 0;
};

dds::Message<msg::TrafficObjects> Message(Time stamp, const std::vector<Spec>& specs) {
  dds::Message<msg::TrafficObjects> m;
  m->header.stamp = dds::ToMsg(stamp);
  dds::SetString(m->header.frame_id, "map");
  dds::ResizeSequence(m->objects, static_cast<std::uint32_t>(specs.size()));
  for (std::size_t i = 0; i < specs.size(); ++i) {
    const Spec& s = specs[i];
    auto& o = m->objects._buffer[i];
    dds::SetString(o.object_id, s.id);
    dds::SetString(o.map_lane_id, "");
    o.object_class = s.object_class;
    o.pose.position = {s.x, s.y, 0.0};
    o.pose.orientation = {0.0, 0.0, std::sin(s.yaw / 2), std::cos(s.yaw / 2)};
    o.size = {s.size.x(), s.size.y(), s.size.z()};
    o.speed_mps = s.speed;
    o.signals = s.signals;
  }
  return m;
}

TEST(TrafficObjects, AreReadWithTheirClassPoseSizeSpeedAndSignals) {
  auto m = Message(TimeFromSeconds(5), {{"veh0",
                                         autodrive_msgs_msg_TrafficObject_Constants_BUS,
                                         1.0,
                                         2.0,
                                         kPi / 2,
                                         {0.9, 0.18, 0.22},
                                         0.4,
                                         1 | 4},
                                        {"ped.3",
                                         autodrive_msgs_msg_TrafficObject_Constants_PEDESTRIAN,
                                         -1,
                                         0,
                                         0,
                                         {0.05, 0.05, 0.13},
                                         0.1,
                                         2},
                                        {"odd", 42, 0, 0, 0, {0.3, 0.1, 0.1}, 0, 0}});
  // A quaternion of any length is a rotation.
  m->objects._buffer[1].pose.orientation = {0, 0, 0, 3.0};
  std::vector<TrafficObject> objects(5);  // more than the message: the vector shrinks
  const TrafficReadReport report = ReadTrafficObjects(*m, objects);
  EXPECT_EQ(report.skipped, 0u);
  EXPECT_EQ(report.first_problem, "");
  ASSERT_EQ(objects.size(), 3u);
  const TrafficObject& bus = objects[0];
  EXPECT_EQ(bus.id, "veh0");
  EXPECT_EQ(bus.object_class, TrafficClass::kBus);
  EXPECT_TRUE(bus.X_MO.translation().isApprox(Eigen::Vector3d(1, 2, 0)));
  EXPECT_TRUE(bus.X_MO.linear().col(0).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_EQ(bus.size_m, Eigen::Vector3d(0.9, 0.18, 0.22));
  EXPECT_EQ(bus.speed_mps, 0.4);
  EXPECT_TRUE(bus.left_indicator);
  EXPECT_FALSE(bus.right_indicator);
  EXPECT_TRUE(bus.brake);
  EXPECT_EQ(objects[1].object_class, TrafficClass::kPedestrian);
  EXPECT_TRUE(objects[1].X_MO.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  EXPECT_TRUE(objects[1].right_indicator);
  EXPECT_FALSE(objects[1].brake);
  EXPECT_EQ(objects[2].object_class, TrafficClass::kUnknown) << "a class the IDL does not have";
}

TEST(TrafficObjects, ABadObjectIsLeftOutAndNamedAndTheOthersAreKept) {
  const auto read = [](const std::function<void(autodrive_msgs_msg_dds__TrafficObject_&)>& spoil) {
    auto m = Message(Time{}, {{"good", 1, 1, 1}, {"bad", 1, 2, 2}, {"good2", 1, 3, 3}});
    spoil(m->objects._buffer[1]);
    std::vector<TrafficObject> objects;
    const TrafficReadReport report = ReadTrafficObjects(*m, objects);
    EXPECT_EQ(report.skipped, 1u);
    EXPECT_EQ(objects.size(), 2u);
    if (objects.size() == 2) {
      EXPECT_EQ(objects[1].id, "good2");
    }
    return report.first_problem;
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(read([&](auto& o) { o.pose.position.x = nan; }),
              HasSubstr("object 1 ('bad'): position (nan, 2, 0)"));
  EXPECT_THAT(read([](auto& o) { o.pose.position.y = 2e4; }), HasSubstr("beyond 10000 m"));
  EXPECT_THAT(read([](auto& o) {
                o.pose.orientation = {0, 0, 0, 0};
              }),
              HasSubstr("orientation (0, 0, 0, 0) is not a rotation"));
  EXPECT_THAT(read([](auto& o) { o.size.z = 0; }),
              HasSubstr("size (0.32, 0.13, 0) m is outside (0, 20]"));
  EXPECT_THAT(read([](auto& o) { o.size.x = 25; }), HasSubstr("size (25, 0.13, 0.11)"));
  EXPECT_THAT(read([&](auto& o) { o.speed_mps = nan; }), HasSubstr("speed nan m/s"));
  EXPECT_THAT(read([](auto& o) { dds::SetString(o.object_id, std::string(300, 'x')); }),
              HasSubstr("its id has 300 characters, more than 256"));
}

TEST(TrafficObjects, AMessageIsTakenUpToTheLimitOnly) {
  std::vector<Spec> specs(kMaxTrafficObjects + 3, Spec{"v", 1, 1, 1});
  const auto m = Message(Time{}, specs);
  std::vector<TrafficObject> objects;
  const TrafficReadReport report = ReadTrafficObjects(*m, objects);
  EXPECT_EQ(objects.size(), kMaxTrafficObjects);
  EXPECT_EQ(report.skipped, 3u);
  EXPECT_THAT(report.first_problem, HasSubstr("20003 objects: only the first 20000"));
}

TEST(TrafficObjects, InRealTimeTheyMoveAlongTheirHeadingForTheMessagesAgeUpToAFifthOfASecond) {
  const Time stamp = TimeFromSeconds(100);
  EXPECT_EQ(TrafficExtrapolation(stamp, stamp + milliseconds(30)), milliseconds(30));
  EXPECT_EQ(TrafficExtrapolation(stamp, stamp + milliseconds(900)), milliseconds(200));
  EXPECT_EQ(TrafficExtrapolation(stamp, stamp - milliseconds(50)), Duration{0})
      << "a stamp from the future is taken as it is";
  TrafficObject o;
  o.X_MO = Eigen::Translation3d(1, 2, 0) * Eigen::AngleAxisd(kPi / 4, Eigen::Vector3d::UnitZ());
  o.speed_mps = 0.5;
  const Eigen::Isometry3d X = TrafficPoseAfter(o, milliseconds(200));
  EXPECT_TRUE(X.translation().isApprox(
      Eigen::Vector3d(1 + 0.1 / std::sqrt(2.0), 2 + 0.1 / std::sqrt(2.0), 0)));
  EXPECT_TRUE(X.linear().isApprox(o.X_MO.linear()));
}

TEST(TrafficObjects, TheirBoxStandsOnTheGroundAndTheirColoursDependOnClassAndIdOnly) {
  TrafficObject o;
  o.size_m = {0.4, 0.2, 0.3};
  o.X_MO = Eigen::Translation3d(1, 2, 0.05) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ());
  const DynamicBox box = TrafficBox(o, o.X_MO, BoxId(7));
  EXPECT_EQ(box.id, BoxId(7));
  EXPECT_TRUE(box.X_MB.translation().isApprox(Eigen::Vector3d(1, 2, 0.2)));
  EXPECT_TRUE(box.X_MB.linear().isApprox(o.X_MO.linear()));
  EXPECT_EQ(box.half_extents_m, Eigen::Vector3d(0.2, 0.1, 0.15));

  // Cars: greys and whites, the same for the same id, several over many ids.
  std::set<std::tuple<int, int, int>> seen;
  for (int i = 0; i < 50; ++i) {
    const std::string id = "flow." + std::to_string(i);
    const TrafficPaint p = TrafficPaintOf(TrafficClass::kCar, id);
    EXPECT_EQ(p.body, TrafficPaintOf(TrafficClass::kCar, id).body);
    EXPECT_EQ(p.body, p.roof);
    EXPECT_LE(std::max({p.body.r, p.body.g, p.body.b}) - std::min({p.body.r, p.body.g, p.body.b}),
              12)
        << "grey or white";
    seen.insert({p.body.r, p.body.g, p.body.b});
  }
  EXPECT_GE(seen.size(), 4u);
  // FNV-1a of "veh0" picks the same colour on every machine.
  EXPECT_EQ(TrafficPaintOf(TrafficClass::kCar, "veh0").body,
            TrafficPaintOf(TrafficClass::kUnknown, "veh0").body);
  const Rgb bus = TrafficPaintOf(TrafficClass::kBus, "a").body;
  EXPECT_GT(bus.r, 200);
  EXPECT_GT(bus.g, 150);
  EXPECT_LT(bus.b, 60) << "yellow";
  const TrafficPaint emergency = TrafficPaintOf(TrafficClass::kEmergency, "a");
  EXPECT_EQ(emergency.body, (Rgb{240, 240, 240}));
  EXPECT_GT(emergency.roof.r, 200);
  EXPECT_LT(emergency.roof.g, 60) << "a red roof on a white body";

  o.object_class = TrafficClass::kTruck;
  o.brake = true;
  o.left_indicator = true;
  const RenderTraffic look = TrafficLook(o, o.X_MO);
  EXPECT_EQ(look.shape, TrafficShape::kTall);
  EXPECT_TRUE(look.brake);
  EXPECT_TRUE(look.left_indicator);
  EXPECT_FALSE(look.right_indicator);
  EXPECT_EQ(look.size_m, o.size_m);
}

// A car (rear axle at the origin, facing +x) drives at full throttle towards a background car
// whose back is 1 m ahead: at the start it is beyond the reach at which the world gives boxes
// to ODE, so this also checks that they are chosen again as the car moves.
TEST(TrafficWorld, ACarDrivenIntoABackgroundCarStopsAgainstItAndTheContactIsReported) {
  World world;
  const int car = world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  const VehicleParams& p = world.Params(car);
  const double front = p.body_centre_ahead_of_rear_axle_m + p.body_length_m / 2;
  const Eigen::Vector3d size(0.32, 0.13, 0.11);
  const double back = 1.0;
  DynamicBox box{BoxId(1), Eigen::Isometry3d::Identity(), size / 2};
  box.X_MB.translation() = Eigen::Vector3d(back + size.x() / 2, 0.0, size.z() / 2);
  // And one far away that nothing touches.
  DynamicBox far = box;
  far.id = BoxId(2);
  far.X_MB.translation().y() = 3.0;
  const std::vector<DynamicBox> boxes{far, box};
  world.SetTraffic(boxes);
  world.SetCommand(car, {1.0, 0.0});
  std::set<int> touched;
  double first_contact_s = -1;
  while (world.time() < std::chrono::seconds(8)) {
    world.Step();
    for (const TrafficContact& c : world.TrafficContacts()) {
      EXPECT_EQ(c.vehicle, car);
      touched.insert(c.traffic);
      if (first_contact_s < 0) first_contact_s = ToSeconds(world.time());
    }
  }
  EXPECT_EQ(touched, std::set<int>{1}) << "the box ahead (index 1), not the far one";
  // At 0.26 m/s the front reaches the box after about (1 - 0.23) / 0.26 = 3 s.
  EXPECT_GT(first_contact_s, 2.5);
  EXPECT_LT(first_contact_s, 4.0);
  // Pushing at full throttle for 4 s more, it stands against the box's back.
  const VehicleState& s = world.State(car);
  const double x_front = s.X_MV.translation().x() + front;
  EXPECT_LT(x_front, back + 0.003) << "it does not go through";
  EXPECT_GT(x_front, back - 0.01) << "it reached the box";
  EXPECT_LT(std::abs(s.v_V_mps.x()), 0.01);
}

// A background car that was within reach and then left it (its ODE box is disabled, where it
// stood) is not there any more: a car driving through where it stood touches nothing. ODE
// collides two spaces by walking the one with fewer geoms, disabled ones included: with fewer
// background boxes than cars (each car is a space of its own), a disabled box used to collide
// where it last stood. So: three cars, and two boxes, one of them staying within reach (so that
// the world collides its boxes at all).
TEST(TrafficWorld, ABackgroundCarThatLeftIsNotThereAnyMore) {
  World world;
  const int car = world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, 0));
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, -5, 0));
  world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, -10, 0));
  const Eigen::Vector3d size(0.32, 0.13, 0.11);
  DynamicBox ahead{BoxId(1), Eigen::Isometry3d::Identity(), size / 2};
  ahead.X_MB.translation() = Eigen::Vector3d(0.6 + size.x() / 2, 0.0, size.z() / 2);
  DynamicBox beside = ahead;  // parked beside the car's path, for the whole run
  beside.id = BoxId(2);
  beside.X_MB.translation() = Eigen::Vector3d(0.5, 0.35, size.z() / 2);
  world.SetTraffic(std::vector<DynamicBox>{beside, ahead});
  world.Step();  // both chosen: within reach of the car
  // The one ahead drives on, 20 m away (out of reach: its ODE box is disabled, not moved).
  ahead.X_MB.translation().x() = 20.0;
  world.SetTraffic(std::vector<DynamicBox>{beside, ahead});
  world.SetCommand(car, {1.0, 0.0});
  std::vector<TrafficContact> contacts;
  while (world.time() < std::chrono::seconds(5)) {
    world.Step();
    contacts.insert(contacts.end(), world.TrafficContacts().begin(), world.TrafficContacts().end());
  }
  EXPECT_TRUE(contacts.empty()) << contacts.size() << " contacts with a car that left";
  EXPECT_GT(world.State(car).X_MV.translation().x(), 1.0) << "it drove through where it stood";
}

// Randomised cross-check: a car's LIDAR among thousands of boxes (where the sensor tests each
// step's beams only against the boxes in their wedge) sees what every beam testing every box
// sees. Seeded; AUTODRIVE_SOAK_FACTOR multiplies the cases.
TEST(TrafficLidar, ThousandsOfBoxesAreSeenAsIfEveryBeamTestedEveryBox) {
  const int cases = 3 * test::SoakFactor();
  int returns_from_boxes = 0;
  for (int c = 0; c < cases; ++c) {
    SCOPED_TRACE("case " + std::to_string(c));
    std::mt19937 rng(static_cast<std::uint32_t>(100 + c));
    std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
    World world;
    const int car =
        world.AddVehicle(VehicleParams{}, RigidTransform2::FromXyYaw(0, 0, kPi * u(rng)));
    std::vector<DynamicBox> boxes;
    for (std::uint32_t k = 0; k < 2000; ++k) {
      DynamicBox b{BoxId(100 + k)};
      b.half_extents_m = {0.02 + 0.3 * u01(rng), 0.02 + 0.1 * u01(rng), 0.02 + 0.2 * u01(rng)};
      // Around the car out to beyond the range; none within 0.5 m.
      const double r = 0.5 + 13.0 * std::sqrt(u01(rng));
      const double a = kPi * u(rng);
      b.X_MB = Eigen::Translation3d(r * std::cos(a), r * std::sin(a), b.half_extents_m.z()) *
               Eigen::AngleAxisd(kPi * u(rng), Eigen::Vector3d::UnitZ()) *
               Eigen::AngleAxisd(k % 5 == 0 ? 0.3 * u(rng) : 0.0, Eigen::Vector3d::UnitX());
      boxes.push_back(b);
    }
    SensorSuite suite(SensorConfig{}, car, 1);
    SensorReadings readings;
    std::vector<DynamicBox> all;
    std::optional<LidarScan> scan;
    while (!scan && world.time() < std::chrono::seconds(1)) {
      world.Step();
      VehicleBoxes(world, all);
      all.insert(all.end(), boxes.begin(), boxes.end());
      suite.Sample(world, world.Scene(), all, readings);
      if (readings.lidar && readings.lidar->stamp > Duration{0}) scan = readings.lidar;
    }
    ASSERT_TRUE(scan.has_value());
    // The reference: the car stands still, so every beam from its pose now.
    const LidarConfig& l = suite.config().lidar;
    const VehicleState& s = world.State(car);
    const Eigen::Isometry3d X_ML = Eigen::Translation3d(s.X_MV.translation()) * s.X_MV.rotation() *
                                   Eigen::Translation3d(l.x_m, l.y_m, l.z_m) *
                                   Eigen::AngleAxisd(l.yaw_rad, Eigen::Vector3d::UnitZ());
    for (int i = 0; i < l.beams; ++i) {
      const double a = scan->angle_min_rad + i * scan->angle_increment_rad;
      const Ray ray{X_ML.translation(),
                    X_ML.linear() * Eigen::Vector3d(std::cos(a), std::sin(a), 0)};
      const Hit hit = CastBruteForce(world.Scene(), all, ray, l.range_max_m, BoxId(0));
      const float range = scan->ranges[static_cast<std::size_t>(i)];
      const bool expected = hit.range_m >= l.range_min_m && hit.range_m < l.range_max_m;
      if (!expected) {
        EXPECT_TRUE(std::isinf(range)) << "beam " << i << ": " << range;
        continue;
      }
      EXPECT_NEAR(range, hit.range_m, 1e-4) << "beam " << i;
      returns_from_boxes += hit.what == Hit::What::kBox ? 1 : 0;
    }
  }
  EXPECT_GT(returns_from_boxes, 50 * cases) << "the boxes are in sight";
}

const maps::Map& SmallTown() {
  static const maps::Map map = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / "small_town.yaml").string()));
  return map;
}

Rgb PixelAt(const Image& image, const Eigen::Vector2d& px) {
  const auto u = static_cast<std::size_t>(std::lround(px.x()));
  const auto v = static_cast<std::size_t>(std::lround(px.y()));
  const std::size_t i = 3 * (v * static_cast<std::size_t>(image.width_px) + u);
  return {image.rgb[i], image.rgb[i + 1], image.rgb[i + 2]};
}

TEST(TrafficCameras, AnObjectInViewIsDrawnInItsColoursAndThousandsOutOfViewBuildNothing) {
  RenderWorldOptions options;
  options.ground_texel_m = 0.01;
  const auto world =
      std::make_shared<const RenderWorld>(SmallTown(), GeometryFromMap(SmallTown()), options);
  // Straight down from 3 m over (2.5, 1.5), image top north.
  const camera::Intrinsics intrinsics = camera::IntrinsicsFromSensor(500.0, 640.0, 640, 480);
  const Eigen::Isometry3d X_MC =
      camera::CameraPoseFromMount({2.5, 1.5, 3.0}, {0.0, kPi / 2, kPi / 2});
  const camera::CameraModel model(intrinsics);
  CameraRenderer renderer(world, intrinsics);
  TrafficObject car;
  car.id = "veh7";
  car.X_MO = Eigen::Translation3d(2.3, 1.4, 0) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ());
  TrafficObject bus = car;
  bus.id = "bus1";
  bus.object_class = TrafficClass::kBus;
  bus.size_m = {0.9, 0.18, 0.22};
  bus.X_MO.translation() = Eigen::Vector3d(2.9, 1.8, 0);
  std::vector<RenderTraffic> traffic{TrafficLook(car, car.X_MO), TrafficLook(bus, bus.X_MO)};
  // A city's worth more, all out of this camera's view (but some of them in front of it).
  for (int k = 0; k < 5000; ++k) {
    TrafficObject o = car;
    o.X_MO.translation() = Eigen::Vector3d(20.0 + 0.4 * (k % 100), -30.0 + 0.4 * (k / 100), 0);
    traffic.push_back(TrafficLook(o, o.X_MO));
  }
  FrameState frame;
  frame.traffic = traffic;
  Image image;
  renderer.Render(X_MC, frame, image);
  EXPECT_EQ(renderer.stats().traffic_in_view, 2) << "only the two in view were built";
  // The roofs (the top faces, lit as the ground is) in their colours.
  const auto roof = [&](const Image& in, const TrafficObject& o) {
    const auto px = model.Project(X_MC.inverse() * (o.X_MO * Eigen::Vector3d(0, 0, o.size_m.z())));
    EXPECT_TRUE(px.has_value());
    return px ? PixelAt(in, *px) : Rgb{};
  };
  EXPECT_EQ(roof(image, car), TrafficPaintOf(TrafficClass::kCar, "veh7").roof);
  EXPECT_EQ(roof(image, bus), (Rgb{240, 190, 20}));
  // Without them the ground is there.
  Image empty;
  renderer.Render(X_MC, FrameState{}, empty);
  EXPECT_EQ(renderer.stats().traffic_in_view, 0);
  EXPECT_NE(roof(empty, car), TrafficPaintOf(TrafficClass::kCar, "veh7").roof);
  EXPECT_NE(roof(empty, bus), (Rgb{240, 190, 20}));
}

// A camera 0.5 m behind a background car, at its lamps' height: its brake lights glow when its
// brake bit is set.
TEST(TrafficCameras, BrakeLightsGlowWhileTheBrakeBitIsSet) {
  RenderWorldOptions options;
  options.ground_texel_m = 0.01;
  const auto world =
      std::make_shared<const RenderWorld>(SmallTown(), GeometryFromMap(SmallTown()), options);
  const camera::Intrinsics intrinsics = camera::IntrinsicsFromSensor(500.0, 640.0, 640, 480);
  const camera::CameraModel model(intrinsics);
  CameraRenderer renderer(world, intrinsics);
  TrafficObject car;
  car.id = "veh1";
  car.X_MO = Eigen::Translation3d(2.0, 0.5, 0) * Eigen::AngleAxisd(0.0, Eigen::Vector3d::UnitZ());
  // The tail lights as the renderer places them on the body's back (see AddTraffic).
  const double H = car.size_m.z(), W = car.size_m.y(), L = car.size_m.x();
  const double hz = 0.225 * H, hy = W / 2, lamp = 0.35 * std::min(hy, hz);
  const Eigen::Vector3d lamp_M =
      car.X_MO * Eigen::Vector3d(-L / 2, hy - 3.6 * lamp, 0.375 * H + 0.3 * hz);
  const Eigen::Isometry3d X_MC =
      camera::CameraPoseFromMount({lamp_M.x() - 0.5, 0.5, lamp_M.z()}, {0.0, 0.0, 0.0});
  const auto lamp_colour = [&](bool brake) {
    car.brake = brake;
    const std::vector<RenderTraffic> traffic{TrafficLook(car, car.X_MO)};
    FrameState frame;
    frame.traffic = traffic;
    Image image;
    renderer.Render(X_MC, frame, image);
    const auto px = model.Project(X_MC.inverse() * lamp_M);
    EXPECT_TRUE(px.has_value());
    return px ? PixelAt(image, *px) : Rgb{};
  };
  EXPECT_EQ(lamp_colour(true), (Rgb{255, 40, 40}));
  const Rgb off = lamp_colour(false);
  EXPECT_LT(off.r, 160);
  EXPECT_GT(off.r, off.g) << "a dark red lamp";
}

}  // namespace
}  // namespace autodrive::vehicle_sim
