// autodrive-sim as a process: a car driven over DDS with the devkit command topics from this
// (separate) process, its devkit sensor topics read back, and the command time-out.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/process.h"
#include "common/test_support.h"
#include "tests/scm_processes.h"

namespace autodrive::test {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

class SimProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    partition_ = fmt::format("sim_{}_{}", ::getpid(), info->name());
    dir_ = std::filesystem::temp_directory_path() / partition_;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    participant_ = std::make_unique<dds::Participant>(dds::ParticipantOptions{{}, partition_, {}});
  }
  void TearDown() override {
    sim_.reset();
    std::filesystem::remove_all(dir_);
  }
  // A city of one car, nigel_7, on the small town's southern road facing east.
  std::string WriteCity() const {
    const std::string path = (dir_ / "city.yaml").string();
    std::ofstream(path)
        << "name: sim_test\nmap: " << Config("config/maps/small_town.yaml")
        << "\nsim:\n  vehicles:\n    - {name: nigel_7, spawn: {lane: \"r4c1:W>E:0\", "
           "along_m: 0.2}}\n";
    return path;
  }
  void StartSim(std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{Bin("autodrive-sim"), "--city",      WriteCity(), "--partition",
                                  partition_,           "--log-level", "warn"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    sim_ = std::make_unique<ChildProcess>(argv);
  }
  // Waits for a sample of `reader` that `pred` likes.
  template <typename T, typename P>
  std::optional<dds::Message<T>> WaitFor(dds::Reader<T>& reader, P pred,
                                         std::chrono::steady_clock::duration timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      reader.WaitForData(milliseconds(50));
      while (auto m = reader.TakeOne()) {
        if (pred(**m)) return m;
      }
    }
    return std::nullopt;
  }

  std::string partition_;
  std::filesystem::path dir_;
  std::unique_ptr<dds::Participant> participant_;
  std::unique_ptr<ChildProcess> sim_;
};

TEST_F(SimProcess, ACarDrivenOverTheDevkitTopicsMovesAndReportsOnEveryDevkitSensorTopic) {
  const VehicleId car(7);
  dds::Writer<msg::Float32> throttle(*participant_, dds::topics::ThrottleCommand(car));
  dds::Writer<msg::Float32> steering(*participant_, dds::topics::SteeringCommand(car));
  dds::Reader<msg::Point> ips(*participant_, dds::topics::Ips(car));
  dds::Reader<msg::LaserScan> lidar(*participant_, dds::topics::Lidar(car));
  dds::Reader<msg::Imu> imu(*participant_, dds::topics::Imu(car));
  dds::Reader<msg::JointState> left(*participant_, dds::topics::LeftEncoder(car));
  dds::Reader<msg::JointState> right(*participant_, dds::topics::RightEncoder(car));
  dds::Reader<msg::Float32> throttle_feedback(*participant_, dds::topics::Throttle(car));
  dds::Reader<msg::Float32> steering_feedback(*participant_, dds::topics::Steering(car));
  dds::Reader<msg::TrackedVehicle> truth(*participant_, dds::topics::GroundTruth(car));
  dds::Reader<msg::Clock> clock(*participant_, dds::topics::Clock());
  StartSim();

  // Before any command: the car stands at its spawn point, on the southern road.
  const auto start = WaitFor(
      ips, [](const msg::Point&) { return true; }, seconds(60));
  ASSERT_TRUE(start.has_value()) << "no ips from the simulator";
  EXPECT_NEAR((*start)->y, 0.35, 0.05);  // the eastbound lane of row 4: 0.5 - 0.15
  const double x0 = (*start)->x;
  ASSERT_TRUE(WaitFor(
      clock, [](const msg::Clock& c) { return c.clock.sec > 0; }, seconds(30)));

  // Half throttle, straight: the car drives east along its lane.
  ASSERT_TRUE(throttle.WaitForReaders(1, seconds(30)));
  ASSERT_TRUE(steering.WaitForReaders(1, seconds(30)));
  const auto drive_until = [&](auto done, std::chrono::steady_clock::duration timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      throttle.Write(msg::Float32{0.5F});
      steering.Write(msg::Float32{0.0F});
      ips.WaitForData(milliseconds(50));
      while (auto m = ips.TakeOne()) {
        if (done(**m)) return true;
      }
    }
    return false;
  };
  EXPECT_TRUE(drive_until([&](const msg::Point& p) { return p.x > x0 + 0.25; }, seconds(60)))
      << "the car did not drive 0.25 m east";

  // Every devkit sensor topic reports, with the devkit's shapes.
  const auto scan = WaitFor(
      lidar, [](const msg::LaserScan&) { return true; }, seconds(10));
  ASSERT_TRUE(scan.has_value());
  EXPECT_EQ((*scan)->ranges._length, 360u);
  EXPECT_FLOAT_EQ((*scan)->range_min, 0.15F);
  EXPECT_FLOAT_EQ((*scan)->range_max, 12.0F);
  EXPECT_STREQ((*scan)->header.frame_id, "lidar");
  const auto accel = WaitFor(
      imu, [](const msg::Imu&) { return true; }, seconds(10));
  ASSERT_TRUE(accel.has_value());
  EXPECT_NEAR((*accel)->linear_acceleration.z, 9.81, 0.5);
  const auto encoder = WaitFor(
      left, [](const msg::JointState& js) { return js.position._length == 1; }, seconds(10));
  ASSERT_TRUE(encoder.has_value());
  EXPECT_GT((*encoder)->position._buffer[0], 0.25 / 0.0325 * 0.8);  // radians turned so far
  EXPECT_TRUE(WaitFor(
      right, [](const msg::JointState& js) { return js.position._length == 1; }, seconds(10)));
  EXPECT_TRUE(WaitFor(
      throttle_feedback, [](const msg::Float32& f) { return f.data == 0.5F; }, seconds(10)));
  EXPECT_TRUE(WaitFor(
      steering_feedback, [](const msg::Float32&) { return true; }, seconds(10)));
  const auto gt = WaitFor(
      truth, [](const msg::TrackedVehicle&) { return true; }, seconds(10));
  ASSERT_TRUE(gt.has_value());
  EXPECT_STREQ((*gt)->vehicle_id, "nigel_7");
  EXPECT_EQ((*gt)->source, autodrive_msgs_msg_TrackedVehicle_Constants_SIM_GROUND_TRUTH);
  EXPECT_NEAR((*gt)->twist.twist.linear.x, 0.13, 0.03);  // half of 0.26 m/s

  // The commands stop: after the time-out (0.5 s) the car holds still.
  const auto stopped_by = std::chrono::steady_clock::now() + seconds(60);
  double last_x = 0;
  int still = 0;
  while (std::chrono::steady_clock::now() < stopped_by && still < 20) {
    ips.WaitForData(milliseconds(50));
    while (auto m = ips.TakeOne()) {
      still = std::abs((*m)->x - last_x) < 1e-5 ? still + 1 : 0;
      last_x = (*m)->x;
    }
  }
  EXPECT_GE(still, 20) << "the car kept moving without commands";
  EXPECT_EQ(sim_->Stop(), 0);
}

TEST_F(SimProcess, ABadCityFileIsRefusedWithTheFileAndKeyNamed) {
  const std::string path = (dir_ / "bad.yaml").string();
  std::ofstream(path) << "name: bad\nmap: " << Config("config/maps/small_town.yaml")
                      << "\nsim:\n  vehicles:\n    - {name: car_1}\n";
  ChildProcess p({Bin("autodrive-sim"), "--city", path, "--partition", partition_}, {});
  const auto code = p.Wait(std::chrono::milliseconds(60000));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 1);
}

}  // namespace
}  // namespace autodrive::test
