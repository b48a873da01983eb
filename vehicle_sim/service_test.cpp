// The simulator's DDS service in-process, on real DDS: lockstep with a controller on this
// thread.
#include "vehicle_sim/service.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <sstream>
#include <thread>

#include "common/camera/camera_model.h"
#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "vehicle_sim/traffic.h"

namespace autodrive::vehicle_sim {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

const maps::Map& SmallTown() {
  static const maps::Map map = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / "small_town.yaml").string()));
  return map;
}

Duration ToDuration(const msg::Time& t) { return dds::FromMsg(t) - Time{}; }

// A lockstep simulator of one car (nigel_1 on the southern road) in its own thread, and this
// test as its controller "ctl".
class Lockstep {
 public:
  explicit Lockstep(const std::string& partition, std::uint64_t seed = 1,
                    const std::function<void(SimCity&)>& edit = {},
                    const std::function<void(ServiceOptions&)>& edit_options = {})
      : participant_(dds::ParticipantOptions{{}, partition, {}}),
        steps_(participant_, dds::topics::SimStep()),
        done_(participant_, dds::topics::SimStepDone()),
        throttle_(participant_, dds::topics::ThrottleCommand(VehicleId(1))),
        steering_(participant_, dds::topics::SteeringCommand(VehicleId(1))),
        truth_(participant_, dds::topics::GroundTruth(VehicleId(1))) {
    SimCity city;
    city.name = "lockstep_test";
    city.sim.seed = seed;
    city.sim.vehicles[0].spawn = SpawnConfig{"r4c1:W>E:0", 0.2, {}, {}, {}};
    city.sim.variability.preset = VariabilityPreset::kPaper;  // noise, drawn from the seed
    if (edit) edit(city);
    ServiceOptions options;
    options.mode = SimMode::kLockstep;
    options.controllers = {"ctl"};
    if (edit_options) edit_options(options);
    service_ = std::make_unique<SimService>(participant_, city, SmallTown(), options);
    service_->LogTo(&log_);
    thread_ = std::thread([this] { service_->Run(stop_); });
  }
  ~Lockstep() {
    stop_.store(true);
    thread_.join();
  }
  void Register() {
    ASSERT_TRUE(done_.WaitForReaders(1, seconds(30)));
    Answer(msg::Time{0, 0});
  }
  // The next step's stamp, or nothing within `timeout`.
  std::optional<Duration> NextStep(std::chrono::steady_clock::duration timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    do {
      if (auto m = steps_.TakeOne()) return ToDuration((*m)->stamp);
    } while (steps_.WaitForData(milliseconds(20)) || std::chrono::steady_clock::now() < end);
    return std::nullopt;
  }
  // Commands for the step at `t`, then the answer.
  void Command(Duration t, float throttle, float steering) {
    throttle_.Write(msg::Float32{throttle});
    steering_.Write(msg::Float32{steering});
    ASSERT_TRUE(throttle_.WaitForAcks(seconds(10)));
    ASSERT_TRUE(steering_.WaitForAcks(seconds(10)));
    Answer(dds::ToMsg(Time{} + t));
  }
  // The newest ground truth (x) delivered so far.
  std::optional<double> TruthX() {
    std::optional<double> x;
    while (auto m = truth_.TakeOne()) x = (*m)->pose.pose.position.x;
    return x;
  }
  // The newest ground truth's pose (x, y, yaw) delivered so far.
  std::optional<RigidTransform2> TruthPose() {
    std::optional<RigidTransform2> pose;
    while (auto m = truth_.TakeOne()) {
      pose = dds::FromMsg((*m)->pose.pose).ToRigidTransform2();
    }
    return pose;
  }
  std::string log() const { return log_.str(); }
  const dds::Participant& participant() const { return participant_; }
  const SimService& service() const { return *service_; }
  // Answers the step at `t` with no command.
  void Pass(Duration t) { Answer(dds::ToMsg(Time{} + t)); }

 private:
  void Answer(const msg::Time& stamp) {
    msg::Header h{};
    h.stamp = stamp;
    dds::BorrowString(h.frame_id, "ctl");
    done_.Write(h);
  }
  dds::Participant participant_;
  dds::Reader<msg::Header> steps_;
  dds::Writer<msg::Header> done_;
  dds::Writer<msg::Float32> throttle_, steering_;
  dds::Reader<msg::TrackedVehicle> truth_;
  std::ostringstream log_;
  std::unique_ptr<SimService> service_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

std::string Partition() {
  return fmt::format("lockstep_{}_{}", ::getpid(),
                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
}

TEST(SimLockstep, ACitysServiceSectionIsCheckedWithTheKeyNamed) {
  const auto load = [](const std::string& service) {
    return test::ErrorMessage<ConfigError>(
        [&] { (void)config::LoadString<SimConfig>("service: " + service + "\n", "city.yaml"); });
  };
  EXPECT_THAT(load("{mode: lockstep}"), testing::HasSubstr("lockstep needs at least one"));
  EXPECT_THAT(load("{mode: lockstep, controllers: [a, a]}"),
              testing::HasSubstr("a is listed twice"));
  EXPECT_THAT(load("{mode: lockstep, stages: [[a], [b, a]]}"),
              testing::HasSubstr("stages: a is listed twice"));
  EXPECT_THAT(load("{mode: lockstep, stages: [[a]], controllers: [a]}"),
              testing::HasSubstr("controllers: a is listed twice"));
  EXPECT_THAT(load("{mode: lockstep, stages: [[]]}"),
              testing::HasSubstr("stages: a stage cannot be empty"));
  EXPECT_THAT(load("{mode: lockstep, stages: [[end]]}"),
              testing::HasSubstr("stages: a controller cannot be named 'end'"));
  EXPECT_THAT(load("{mode: fast, stages: [[a]]}"),
              testing::HasSubstr("stages: only lockstep has stages of controllers"));
  EXPECT_THAT(load("{mode: lockstepp, controllers: [a]}"), testing::HasSubstr("mode"));
  EXPECT_THAT(load("{control_period_s: 0}"), testing::HasSubstr("control_period_s"));
  const auto ok = config::LoadString<SimConfig>(
      "service: {mode: lockstep, controllers: [driver], duration_s: 12}\n", "city.yaml");
  EXPECT_EQ(ok.service.mode, SimMode::kLockstep);
  EXPECT_EQ(ok.service.duration, std::optional<Duration>(seconds(12)));
  const auto staged = config::LoadString<SimConfig>(
      "service: {mode: lockstep, stages: [[lights], [scm, eye]]}\n", "city.yaml");
  EXPECT_EQ(staged.service.stages,
            (std::vector<std::vector<std::string>>{{"lights"}, {"scm", "eye"}}));
  EXPECT_TRUE(staged.service.controllers.empty());
}

TEST(SimLockstep, TheWorldAdvancesOneControlPeriodPerAnswerAndWaitsForIt) {
  Lockstep sim(Partition());
  // Nothing happens before the controller registers.
  EXPECT_FALSE(sim.NextStep(milliseconds(300)).has_value());
  sim.Register();
  const auto first = sim.NextStep(seconds(30));
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(*first, Duration{0});
  Duration t = *first;
  for (int k = 1; k <= 50; ++k) {
    sim.Command(t, 1.0F, 0.0F);
    const auto next = sim.NextStep(seconds(30));
    ASSERT_TRUE(next.has_value()) << "step " << k;
    EXPECT_EQ(*next - t, milliseconds(10)) << "one control period per answer";
    t = *next;
  }
  // Unanswered, the simulator waits: no step, no time passes.
  EXPECT_FALSE(sim.NextStep(milliseconds(300)).has_value());
  EXPECT_EQ(sim.service().time(), milliseconds(500));
  // Every step's ground truth arrived before the step was announced.
  const auto x = sim.TruthX();
  ASSERT_TRUE(x.has_value());
  EXPECT_GT(*x, 0.05);
}

// The same seed and the same controller give the same log, byte for byte (with the paper's
// noise on, drawn from the seed); the controller's decisions depend on what it was sent.
TEST(SimLockstep, TwoRunsWithTheSameSeedAndControllerGiveTheSameLog) {
  const auto run = [](std::uint64_t seed, const std::string& partition) {
    Lockstep sim(partition, seed);
    sim.Register();
    auto t = sim.NextStep(seconds(30));
    double x = 0;
    for (int k = 0; k < 150 && t; ++k) {
      if (auto seen = sim.TruthX()) x = *seen;
      // Drive to 0.2 m past the start, then brake; steer from what was seen.
      const float throttle = x < 0.9 ? 1.0F : 0.0F;
      sim.Command(*t, throttle, static_cast<float>(std::sin(10 * x)) * 0.5F);
      t = sim.NextStep(seconds(30));
    }
    EXPECT_TRUE(t.has_value());
    return sim.log();
  };
  const std::string a = run(3, Partition() + "_a");
  const std::string b = run(3, Partition() + "_b");
  const std::string c = run(4, Partition() + "_c");
  EXPECT_GT(a.size(), 150u * 100);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c) << "another seed, other noise";
}

// Nigel's front camera (small, for speed) and an overhead camera, in lockstep.
void WithCameras(SimCity& city) {
  auto& front = city.sim.vehicles[0].sensors.front_camera;
  front.enabled = true;
  front.rate_hz = 20.0;
  front.lens.width_px = 320;
  front.lens.height_px = 180;
  front.film.noise_sigma = 2.0;  // from the seed: a reproducible run has the same noise
  OverheadCameraConfig overhead;
  overhead.name = "ceiling";
  overhead.rate_hz = 10.0;
  overhead.lens.width_px = 480;
  overhead.lens.height_px = 270;
  overhead.lens.focal_length_mm = 1.5;
  overhead.mount = {2.5, 1.5, 3.0, 0.0, kPi / 2, kPi / 2};
  city.sim.cameras.push_back(overhead);
}

struct Frames {
  std::vector<std::pair<Duration, std::vector<std::uint8_t>>> front, ceiling;
};

TEST(SimCameras, InLockstepEveryFrameIsPublishedAtItsRateStampedAndReproducible) {
  // `read_ceiling` false: nobody reads the overhead camera, which then draws nothing.
  const auto run = [](const std::string& partition, bool read_ceiling = true) {
    Lockstep sim(partition, 5, WithCameras);
    dds::Reader<msg::Image> front(sim.participant(), dds::topics::FrontCamera(VehicleId(1)));
    std::optional<dds::Reader<msg::Image>> ceiling;
    if (read_ceiling) ceiling.emplace(sim.participant(), dds::topics::OverheadCamera("ceiling"));
    Frames frames;
    const auto take = [&](dds::Reader<msg::Image>& reader, auto& into, const char* frame_id,
                          std::uint32_t w, std::uint32_t h) {
      while (auto m = reader.TakeOne()) {
        const msg::Image& image = **m;
        EXPECT_EQ(dds::View(image.header.frame_id), frame_id);
        EXPECT_EQ(dds::View(image.encoding), "rgb8");
        EXPECT_EQ(image.width, w);
        EXPECT_EQ(image.height, h);
        EXPECT_EQ(image.step, 3 * w);
        EXPECT_EQ(image.data._length, 3 * w * h);
        into.emplace_back(
            ToDuration(image.header.stamp),
            std::vector<std::uint8_t>(image.data._buffer, image.data._buffer + image.data._length));
      }
    };
    sim.Register();
    auto t = sim.NextStep(seconds(30));
    // One simulated second (100 steps), driving ahead.
    for (int k = 0; k < 100 && t; ++k) {
      take(front, frames.front, "front_camera", 320, 180);
      if (ceiling) take(*ceiling, frames.ceiling, "ceiling", 480, 270);
      sim.Command(*t, 0.8F, 0.0F);
      t = sim.NextStep(seconds(30));
    }
    EXPECT_TRUE(t.has_value());
    take(front, frames.front, "front_camera", 320, 180);
    if (ceiling) take(*ceiling, frames.ceiling, "ceiling", 480, 270);
    EXPECT_EQ(sim.service().camera_frames(), frames.front.size() + frames.ceiling.size());
    return frames;
  };
  const Frames a = run(Partition() + "_a");
  // 1.01 s of frames at 20 and 10 Hz: frames at 0 (the first step), 0.05, ... 1.0 s.
  ASSERT_EQ(a.front.size(), 21u);
  ASSERT_EQ(a.ceiling.size(), 11u);
  for (std::size_t k = 0; k < a.front.size(); ++k) {
    // Stamped with the step that rendered it: the first step at or after j / rate.
    const Duration due = milliseconds(50) * static_cast<int>(k);
    EXPECT_GE(a.front[k].first, due);
    EXPECT_LT(a.front[k].first, due + milliseconds(3));
  }
  // The car drives: its front camera's view changes; the fixed camera's does where the car is.
  EXPECT_NE(a.front.front().second, a.front.back().second);
  EXPECT_NE(a.ceiling.front().second, a.ceiling.back().second);
  const Frames b = run(Partition() + "_b");
  ASSERT_EQ(b.front.size(), a.front.size());
  ASSERT_EQ(b.ceiling.size(), a.ceiling.size());
  for (std::size_t k = 0; k < a.front.size(); ++k) {
    EXPECT_EQ(a.front[k].first, b.front[k].first);
    EXPECT_TRUE(a.front[k].second == b.front[k].second) << "front frame " << k << " differs";
  }
  for (std::size_t k = 0; k < a.ceiling.size(); ++k) {
    EXPECT_TRUE(a.ceiling[k].second == b.ceiling[k].second) << "overhead frame " << k;
  }
  // Nobody reads the overhead camera: it draws nothing, and the front camera's frames are
  // the same as when both were drawn.
  const Frames c = run(Partition() + "_c", false);
  EXPECT_TRUE(c.ceiling.empty());
  ASSERT_EQ(c.front.size(), a.front.size());
  for (std::size_t k = 0; k < a.front.size(); ++k) {
    EXPECT_TRUE(a.front[k].second == c.front[k].second) << "front frame " << k << " differs";
  }
}

TEST(SimCameras, InRealTimeEachCameraRendersOnItsOwnThreadAndStopsCleanly) {
  // The service in real time on this process's threads: its camera workers render and publish
  // while the loop steps; stopping joins them (ThreadSanitizer runs this test).
  dds::Participant participant(dds::ParticipantOptions{{}, Partition(), {}});
  SimCity city;
  city.name = "realtime_cameras";
  city.sim.vehicles[0].spawn = SpawnConfig{"r4c1:W>E:0", 0.2, {}, {}, {}};
  WithCameras(city);
  ServiceOptions options;  // real time
  SimService service(participant, city, SmallTown(), options);
  dds::Reader<msg::Image> front(participant, dds::topics::FrontCamera(VehicleId(1)));
  dds::Reader<msg::Image> ceiling(participant, dds::topics::OverheadCamera("ceiling"));
  std::atomic<bool> stop{false};
  std::thread loop([&] { service.Run(stop); });
  int fronts = 0, ceilings = 0;
  const auto end = std::chrono::steady_clock::now() + seconds(60);
  while ((fronts < 5 || ceilings < 3) && std::chrono::steady_clock::now() < end) {
    (void)front.WaitForData(milliseconds(50));
    while (auto m = front.TakeOne()) fronts += (*m)->width == 320 ? 1 : 0;
    while (auto m = ceiling.TakeOne()) ceilings += (*m)->width == 480 ? 1 : 0;
  }
  stop.store(true);
  loop.join();
  EXPECT_GE(fronts, 5);
  EXPECT_GE(ceilings, 3);
}

// --- Background traffic ----------------------------------------------------------------------

// One SUMO vehicle for a TrafficObjects message: at `X_MO` (its footprint's centre), of `size`.
struct TrafficSpec {
  std::string id;
  std::uint8_t object_class = autodrive_msgs_msg_TrafficObject_Constants_CAR;
  RigidTransform2 X_MO;
  Eigen::Vector3d size{0.32, 0.13, 0.11};
  double speed_mps = 0;
};

// Publishes `specs` stamped `t` as the traffic process does in lockstep: before answering the
// step, acknowledged.
void PublishTraffic(dds::Writer<msg::TrafficObjects>& writer, Duration t,
                    const std::vector<TrafficSpec>& specs) {
  dds::Message<msg::TrafficObjects> m;
  m->header.stamp = dds::ToMsg(Time{} + t);
  dds::SetString(m->header.frame_id, "map");
  dds::ResizeSequence(m->objects, static_cast<std::uint32_t>(specs.size()));
  for (std::size_t i = 0; i < specs.size(); ++i) {
    const TrafficSpec& s = specs[i];
    auto& o = m->objects._buffer[i];
    dds::SetString(o.object_id, s.id);
    dds::SetString(o.map_lane_id, "");
    o.object_class = s.object_class;
    const double yaw = s.X_MO.rotation().angle();
    o.pose.position = {s.X_MO.translation().x(), s.X_MO.translation().y(), 0.0};
    o.pose.orientation = {0.0, 0.0, std::sin(yaw / 2), std::cos(yaw / 2)};
    o.size = {s.size.x(), s.size.y(), s.size.z()};
    o.speed_mps = s.speed_mps;
  }
  writer.Write(m);
  ASSERT_TRUE(writer.WaitForAcks(seconds(10)));
}

// The range at which a ray from (0, 0) in direction `angle` first meets the rectangle
// [x0, x1] x [y0, y1] (a box seen in the plane of the LIDAR), or none.
std::optional<double> RayRectangle(double angle, double x0, double x1, double y0, double y1) {
  const double dx = std::cos(angle), dy = std::sin(angle);
  double near = 0, far = 1e9;
  for (const auto& [d, lo, hi] : {std::tuple{dx, x0, x1}, std::tuple{dy, y0, y1}}) {
    if (std::abs(d) < 1e-12) {
      if (lo > 0 || hi < 0) return std::nullopt;
      continue;
    }
    const double t0 = std::min(lo / d, hi / d), t1 = std::max(lo / d, hi / d);
    near = std::max(near, t0);
    far = std::min(far, t1);
  }
  if (near > far || near <= 0) return std::nullopt;
  return near;
}

// The pixel of `image` (rgb8, `width` wide) nearest `px`.
Rgb PixelOf(const std::vector<std::uint8_t>& image, std::uint32_t width,
            const Eigen::Vector2d& px) {
  const auto i = 3 * (static_cast<std::size_t>(std::lround(px.y())) * width +
                      static_cast<std::size_t>(std::lround(px.x())));
  return {image[i], image[i + 1], image[i + 2]};
}

// A bus (taller than Nigel's LIDAR plane at 0.1757 m; a 1:14 sedan is not) stands with its back
// 1 m ahead of nigel_1's rear axle and 0.25 m to its left, heading the same way and driving on
// at 0.3 m/s: the LIDAR's beams 6-21 (i degrees counter-clockwise from the car's front, from
// the mount 0.1445 m ahead of the axle) meet its back and right side where the geometry says,
// and in lockstep it stays where the message put it (no extrapolation by its speed). The
// overhead camera draws its yellow roof where it stands. A message without it removes it.
TEST(SimTraffic, ABackgroundBusIsSeenAndDrawnWhereTheMessagePutsItUntilAMessageLeavesItOut) {
  Lockstep sim(Partition(), 1, [](SimCity& city) {
    city.sim.variability.preset = VariabilityPreset::kNone;  // exact ranges, no random boxes
    OverheadCameraConfig overhead;
    overhead.name = "ceiling";
    overhead.rate_hz = 10.0;
    overhead.lens.width_px = 480;
    overhead.lens.height_px = 270;
    overhead.lens.focal_length_mm = 1.5;
    overhead.mount = {2.5, 1.5, 3.0, 0.0, kPi / 2, kPi / 2};
    city.sim.cameras.push_back(overhead);
  });
  OverheadCameraConfig ceiling_config;
  ceiling_config.lens.width_px = 480;
  ceiling_config.lens.height_px = 270;
  ceiling_config.lens.focal_length_mm = 1.5;
  ceiling_config.mount = {2.5, 1.5, 3.0, 0.0, kPi / 2, kPi / 2};
  const camera::CameraModel ceiling_model(ceiling_config.Intrinsics());
  const Eigen::Isometry3d X_MC = ceiling_config.mount.OpticalPose();

  dds::Writer<msg::TrafficObjects> traffic(sim.participant(), dds::topics::Traffic());
  dds::Reader<msg::LaserScan> lidar(sim.participant(), dds::topics::Lidar(VehicleId(1)));
  dds::Reader<msg::Image> ceiling(sim.participant(), dds::topics::OverheadCamera("ceiling"));
  ASSERT_TRUE(traffic.WaitForReaders(1, seconds(30))) << "the simulator reads the traffic";
  sim.Register();
  std::optional<Duration> t = sim.NextStep(seconds(30));
  ASSERT_TRUE(t.has_value());
  const std::optional<RigidTransform2> X_MV = sim.TruthPose();
  ASSERT_TRUE(X_MV.has_value());

  const Eigen::Vector3d size(0.9, 0.18, 0.22);
  const double back = 1.0, left = 0.25;
  const RigidTransform2 X_MO = *X_MV * RigidTransform2::FromXyYaw(back + size.x() / 2, left, 0.0);
  const Duration added = *t;
  PublishTraffic(traffic, *t,
                 {{"bus_7", autodrive_msgs_msg_TrafficObject_Constants_BUS, X_MO, size, 0.3}});

  // The bus in the LIDAR's plane, in the LIDAR's position's frame (x forward).
  constexpr double kLidarX = 0.1445;
  const auto expected = [&](int beam) {
    return RayRectangle(beam * kPi / 180, back - kLidarX, back + size.x() - kLidarX,
                        left - size.y() / 2, left + size.y() / 2);
  };
  int beams_on_bus = 0;
  for (int i = 0; i < 360; ++i) beams_on_bus += expected(i).has_value() ? 1 : 0;
  EXPECT_EQ(beams_on_bus, 16) << "beams 6-21";

  // Steps until the overhead camera drew a frame and a scan that started 0.1 s or more after
  // the bus came (by then a bus moved by its speed would stand 3 cm further) came in.
  const auto run_until = [&](Duration since, std::vector<float>& scan,
                             std::vector<std::uint8_t>& frame) {
    scan.clear();
    frame.clear();
    for (int k = 0; k < 100 && t && (scan.empty() || frame.empty()); ++k) {
      sim.Pass(*t);
      t = sim.NextStep(seconds(30));
      while (auto m = lidar.TakeOne()) {
        const msg::LaserScan& s = **m;
        if (dds::FromMsg(s.header.stamp) - Time{} >= since + milliseconds(100)) {
          scan.assign(s.ranges._buffer, s.ranges._buffer + s.ranges._length);
        }
      }
      while (auto m = ceiling.TakeOne()) {
        const msg::Image& im = **m;
        if (dds::FromMsg(im.header.stamp) - Time{} > since) {
          frame.assign(im.data._buffer, im.data._buffer + im.data._length);
        }
      }
    }
  };
  std::vector<float> scan;
  std::vector<std::uint8_t> frame;
  run_until(added, scan, frame);
  ASSERT_EQ(scan.size(), 360u);
  ASSERT_FALSE(frame.empty());
  for (int i = 0; i < 360; ++i) {
    if (const auto range = expected(i)) {
      EXPECT_NEAR(scan[static_cast<std::size_t>(i)], *range, 0.01) << "beam " << i;
    }
  }
  const Eigen::Vector2d centre = X_MO.translation();
  const auto roof_px =
      ceiling_model.Project(X_MC.inverse() * Eigen::Vector3d(centre.x(), centre.y(), size.z()));
  ASSERT_TRUE(roof_px.has_value());
  EXPECT_EQ(PixelOf(frame, 480, *roof_px), (Rgb{240, 190, 20})) << "a yellow roof";

  // The next message leaves it out: gone from the scans and the frames.
  ASSERT_TRUE(t.has_value());
  const Duration removed = *t;
  PublishTraffic(traffic, *t, {});
  run_until(removed, scan, frame);
  ASSERT_EQ(scan.size(), 360u);
  ASSERT_FALSE(frame.empty());
  for (int i = 0; i < 360; ++i) {
    if (const auto range = expected(i)) {
      EXPECT_FALSE(std::abs(scan[static_cast<std::size_t>(i)] - *range) < 0.05) << "beam " << i;
    }
  }
  EXPECT_NE(PixelOf(frame, 480, *roof_px), (Rgb{240, 190, 20}));
}

// nigel_1 at full throttle towards a background car standing with its back 0.6 m ahead of the
// car's rear axle: it stops against it, does not pass through, and the simulator counts it.
TEST(SimTraffic, ALabCarDrivenIntoAStandingBackgroundCarStopsAgainstIt) {
  Lockstep sim(Partition(), 1,
               [](SimCity& city) { city.sim.variability.preset = VariabilityPreset::kNone; });
  dds::Writer<msg::TrafficObjects> traffic(sim.participant(), dds::topics::Traffic());
  ASSERT_TRUE(traffic.WaitForReaders(1, seconds(30)));
  sim.Register();
  std::optional<Duration> t = sim.NextStep(seconds(30));
  ASSERT_TRUE(t.has_value());
  const std::optional<RigidTransform2> X_MV = sim.TruthPose();
  ASSERT_TRUE(X_MV.has_value());
  const Eigen::Vector3d size(0.32, 0.13, 0.11);
  const double back = 0.6;
  PublishTraffic(traffic, *t,
                 {{"veh0", autodrive_msgs_msg_TrafficObject_Constants_CAR,
                   *X_MV * RigidTransform2::FromXyYaw(back + size.x() / 2, 0.0, 0.0), size, 0.0}});
  // (0.6 - 0.23) m at 0.26 m/s takes 1.4 s; then 1.6 s of pushing.
  for (int k = 0; k < 300 && t; ++k) {
    sim.Command(*t, 1.0F, 0.0F);
    t = sim.NextStep(seconds(30));
  }
  ASSERT_TRUE(t.has_value());
  const std::optional<RigidTransform2> end = sim.TruthPose();
  ASSERT_TRUE(end.has_value());
  const VehicleParams nigel;
  const double front = nigel.body_centre_ahead_of_rear_axle_m + nigel.body_length_m / 2;
  const double ahead = (X_MV->inverse() * *end).translation().x() + front;
  EXPECT_LT(ahead, back + 0.003) << "its front does not pass the background car's back";
  EXPECT_GT(ahead, back - 0.01) << "it drove up to it";
  EXPECT_EQ(sim.service().traffic_collisions(), 1);
}

// In real time a background object is moved on along its heading by its speed for the
// message's age, at most 0.2 s: a bus stamped now at 0.3 m/s stands 6 cm further on in every
// scan taken 0.3 s or more later, however late the message came.
TEST(SimTraffic, InRealTimeABackgroundBusIsMovedOnByItsSpeedForAtMostAFifthOfASecond) {
  dds::Participant participant(dds::ParticipantOptions{{}, Partition(), {}});
  SimCity city;
  city.name = "realtime_traffic";
  city.sim.vehicles[0].spawn = SpawnConfig{"r4c1:W>E:0", 0.2, {}, {}, {}};
  SimService service(participant, city, SmallTown(), ServiceOptions{});  // real time
  dds::Writer<msg::TrafficObjects> traffic(participant, dds::topics::Traffic());
  dds::Reader<msg::LaserScan> lidar(participant, dds::topics::Lidar(VehicleId(1)));
  dds::Reader<msg::TrackedVehicle> truth(participant, dds::topics::GroundTruth(VehicleId(1)));
  std::atomic<bool> stop{false};
  std::thread loop([&] { service.Run(stop); });
  const auto deadline = std::chrono::steady_clock::now() + seconds(60);
  // The car's pose and the simulator's time now, from its ground truth.
  std::optional<RigidTransform2> X_MV;
  Time now;
  while (!X_MV && std::chrono::steady_clock::now() < deadline) {
    (void)truth.WaitForData(milliseconds(50));
    while (auto m = truth.TakeOne()) {
      X_MV = dds::FromMsg((*m)->pose.pose).ToRigidTransform2();
      now = dds::FromMsg((*m)->observed);
    }
  }
  std::vector<float> scan;
  if (X_MV) {
    const Eigen::Vector3d size(0.9, 0.18, 0.22);
    PublishTraffic(
        traffic, now - Time{},
        {{"bus_1", autodrive_msgs_msg_TrafficObject_Constants_BUS,
          *X_MV * RigidTransform2::FromXyYaw(1.0 + size.x() / 2, 0.25, 0.0), size, 0.3}});
    // The simulator takes traffic at the start of a period and its time does not wait for
    // this thread: on a loaded machine the bus may come in only several scans after `now` +
    // 0.3 s. The first scan from then on that has something about 0.9 m ahead at beam 16 is
    // the bus (nothing else is there); where it stands is checked below.
    while (scan.empty() && std::chrono::steady_clock::now() < deadline) {
      (void)lidar.WaitForData(milliseconds(50));
      while (auto m = lidar.TakeOne()) {
        const msg::LaserScan& s = **m;
        if (dds::FromMsg(s.header.stamp) >= now + milliseconds(300) && s.ranges._length > 16 &&
            s.ranges._buffer[16] < 1.5F) {
          scan.assign(s.ranges._buffer, s.ranges._buffer + s.ranges._length);
        }
      }
    }
  }
  stop.store(true);
  loop.join();
  ASSERT_TRUE(X_MV.has_value());
  ASSERT_EQ(scan.size(), 360u);
  // Beams 12-20 meet its back, 0.2 s x 0.3 m/s further on than the message put it.
  for (int i = 12; i <= 20; ++i) {
    const auto range = RayRectangle(i * kPi / 180, 1.06 - 0.1445, 1.96 - 0.1445, 0.16, 0.34);
    ASSERT_TRUE(range.has_value()) << "beam " << i;
    EXPECT_NEAR(scan[static_cast<std::size_t>(i)], *range, 0.01) << "beam " << i;
  }
}

TEST(SimTraffic, TrafficFalseInTheServiceSectionLeavesTheTopicUnread) {
  const auto ok = config::LoadString<SimConfig>("service: {traffic: false}\n", "city.yaml");
  EXPECT_FALSE(ok.service.traffic);
  EXPECT_TRUE(config::LoadString<SimConfig>("service: {}\n", "city.yaml").service.traffic);
  EXPECT_THAT(test::ErrorMessage<ConfigError>([] {
                (void)config::LoadString<SimConfig>("service: {traffic: no}\n", "city.yaml");
              }),
              testing::HasSubstr("traffic"));
  Lockstep sim(Partition(), 1, {}, [](ServiceOptions& o) { o.traffic = false; });
  dds::Writer<msg::TrafficObjects> traffic(sim.participant(), dds::topics::Traffic());
  EXPECT_FALSE(traffic.WaitForReaders(1, milliseconds(500))) << "no reader of the topic";
}

}  // namespace
}  // namespace autodrive::vehicle_sim
