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
                    const std::function<void(SimCity&)>& edit = {})
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
  std::string log() const { return log_.str(); }
  const dds::Participant& participant() const { return participant_; }
  const SimService& service() const { return *service_; }

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
  EXPECT_THAT(load("{mode: lockstepp, controllers: [a]}"), testing::HasSubstr("mode"));
  EXPECT_THAT(load("{control_period_s: 0}"), testing::HasSubstr("control_period_s"));
  const auto ok = config::LoadString<SimConfig>(
      "service: {mode: lockstep, controllers: [driver], duration_s: 12}\n", "city.yaml");
  EXPECT_EQ(ok.service.mode, SimMode::kLockstep);
  EXPECT_EQ(ok.service.duration, std::optional<Duration>(seconds(12)));
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
  const auto run = [](const std::string& partition) {
    Lockstep sim(partition, 5, WithCameras);
    dds::Reader<msg::Image> front(sim.participant(), dds::topics::FrontCamera(VehicleId(1)));
    dds::Reader<msg::Image> ceiling(sim.participant(), dds::topics::OverheadCamera("ceiling"));
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
      take(ceiling, frames.ceiling, "ceiling", 480, 270);
      sim.Command(*t, 0.8F, 0.0F);
      t = sim.NextStep(seconds(30));
    }
    EXPECT_TRUE(t.has_value());
    take(front, frames.front, "front_camera", 320, 180);
    take(ceiling, frames.ceiling, "ceiling", 480, 270);
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

}  // namespace
}  // namespace autodrive::vehicle_sim
