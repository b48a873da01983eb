// autodrive-sim as a process: a car driven over DDS with the devkit command topics from this
// (separate) process, its devkit sensor topics read back, and the command time-out.
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/camera_model.h"
#include "common/dds/conversions.h"
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
  // The commands go on while the sensors are checked: a pause of 0.5 s on a loaded machine
  // would let the simulator's command time-out stop the car (and zero its throttle feedback).
  // (A jthread: a failed ASSERT below stops and joins it on the way out.)
  std::jthread driver([&](const std::stop_token& stop) {
    while (!stop.stop_requested()) {
      throttle.Write(msg::Float32{0.5F});
      steering.Write(msg::Float32{0.0F});
      std::this_thread::sleep_for(milliseconds(50));
    }
  });

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
  driver.request_stop();
  driver.join();

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

// Two runs of the simulator in lockstep with the example driver in another process, with the
// paper's noise: the same seed gives the same log, byte for byte.
TEST_F(SimProcess, InLockstepWithADriverInAnotherProcessTwoRunsGiveTheSameLog) {
  const std::string city = (dir_ / "lockstep.yaml").string();
  std::ofstream(city) << "name: lockstep_test\nmap: " << Config("config/maps/small_town.yaml")
                      << "\nsim:\n  seed: 11\n  variability: {preset: paper}\n"
                         "  service: {mode: lockstep, controllers: [driver]}\n"
                         "  vehicles:\n"
                         "    - {name: nigel_1, spawn: {lane: \"r4c1:W>E:0\", along_m: 0.2}}\n"
                         "    - {name: nigel_2, spawn: {lane: \"r2c1:E>W:0\", along_m: 0.2}}\n";
  const auto run = [&](const std::string& name) {
    const std::string partition = partition_ + "_" + name;
    const std::string log = (dir_ / (name + ".csv")).string();
    ChildProcess sim({Bin("autodrive-sim"), "--city", city, "--partition", partition, "--duration",
                      "12", "--log", log, "--log-level", "warn"});
    ChildProcess driver({Bin("autodrive-example-driver"), "--city", city, "--partition", partition,
                         "--lockstep", "driver", "--log-level", "warn"});
    const auto start = std::chrono::steady_clock::now();
    const auto sim_code = sim.Wait(milliseconds(240'000));
    const double took =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("%s: 12 simulated s in lockstep in %.1f s of wall time\n", name.c_str(), took);
    EXPECT_EQ(sim_code, std::optional<int>(0)) << name;
    EXPECT_EQ(driver.Wait(milliseconds(60'000)), std::optional<int>(0))
        << name << ": the driver ends with the simulator";
    std::ifstream in(log, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string a = run("first");
  const std::string b = run("second");
  // 1,201 control periods of two cars, and a header.
  EXPECT_EQ(std::count(a.begin(), a.end(), '\n'), 1 + 2 * 1201);
  EXPECT_TRUE(a == b) << "the two runs' logs differ";
  // The cars drove: nigel_1 east along its lane.
  std::istringstream rows(a);
  std::string line;
  std::getline(rows, line);
  double first_x = NAN, last_x = NAN;
  while (std::getline(rows, line)) {
    if (!line.starts_with("nigel_1,")) continue;
    std::istringstream fields(line);
    std::string field;
    std::getline(fields, field, ',');  // vehicle
    std::getline(fields, field, ',');  // time
    std::getline(fields, field, ',');  // x
    last_x = std::stod(field);
    if (std::isnan(first_x)) first_x = last_x;
  }
  EXPECT_GT(last_x - first_x, 0.5) << "nigel_1 did not drive";
}

// Over DDS, at full throttle: a car stops at an obstacle (an unmapped one, from the city
// file) and two cars driven at each other meet and push, none passing through the other.
TEST_F(SimProcess, ACarStopsAtAWallAndTwoCarsCollideWithoutPassingThroughEachOther) {
  const std::string city = (dir_ / "crash.yaml").string();
  // The southern road (eastbound lane at y = 0.35): nigel_1 from x = 1.2 towards a box whose
  // west face is at x = 2.0; nigel_2 and nigel_3 on the northbound road's line, facing.
  std::ofstream(city) << "name: crash_test\nmap: " << Config("config/maps/small_town.yaml")
                      << "\nsim:\n  variability:\n    obstacles:\n"
                         "      - {x_m: 2.05, y_m: 0.35, length_m: 0.1, width_m: 0.4, "
                         "height_m: 0.2}\n"
                         "  vehicles:\n"
                         "    - {name: nigel_1, spawn: {x_m: 1.2, y_m: 0.35, yaw_rad: 0}}\n"
                         "    - {name: nigel_2, spawn: {x_m: 3.0, y_m: 0.35, yaw_rad: 0}}\n"
                         "    - {name: nigel_3, spawn: {x_m: 4.3, y_m: 0.35, yaw_rad: "
                         "3.14159265}}\n";
  ChildProcess sim(
      {Bin("autodrive-sim"), "--city", city, "--partition", partition_, "--log-level", "warn"});
  std::vector<std::unique_ptr<dds::Writer<msg::Float32>>> throttles;
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> truths;
  for (std::uint32_t i = 1; i <= 3; ++i) {
    throttles.push_back(std::make_unique<dds::Writer<msg::Float32>>(
        *participant_, dds::topics::ThrottleCommand(VehicleId(i))));
    truths.push_back(std::make_unique<dds::Reader<msg::TrackedVehicle>>(
        *participant_, dds::topics::GroundTruth(VehicleId(i))));
  }
  for (auto& w : throttles) ASSERT_TRUE(w->WaitForReaders(1, seconds(60)));
  constexpr double kFront = 0.2297;  // rear axle to the front of the body (Nigel)
  double wall_front = -1e9, wall_speed = 1, min_gap = 1e9, last_gap = 0;
  double t = 0, t_start = -1;
  const auto end = std::chrono::steady_clock::now() + seconds(120);
  std::array<std::optional<double>, 3> x{};
  // Full throttle for 8 simulated seconds.
  while (std::chrono::steady_clock::now() < end && (t_start < 0 || t - t_start < 8.0)) {
    for (auto& w : throttles) w->Write(msg::Float32{1.0F});
    truths[0]->WaitForData(milliseconds(50));
    for (std::size_t i = 0; i < 3; ++i) {
      while (auto m = truths[i]->TakeOne()) {
        const double xi = (*m)->pose.pose.position.x;
        x[i] = xi;
        if (i == 0) {
          t = ToSeconds(dds::FromMsg((*m)->observed) - Time{});
          if (t_start < 0) t_start = t;
          wall_front = std::max(wall_front, xi + kFront);
          wall_speed = std::abs((*m)->twist.twist.linear.x);
        }
      }
    }
    if (x[1] && x[2]) {
      // nigel_3 faces west: its front is at x - kFront.
      last_gap = (*x[2] - kFront) - (*x[1] + kFront);
      min_gap = std::min(min_gap, last_gap);
    }
  }
  std::printf("wall: front reached x = %.4f m (face at 2.0), speed at the end %.4f m/s\n",
              wall_front, wall_speed);
  std::printf("head-on: smallest gap between the fronts %.4f m, at the end %.4f m\n", min_gap,
              last_gap);
  ASSERT_GE(t - t_start, 8.0) << "the simulator did not run 8 s";
  EXPECT_GT(wall_front, 1.98) << "nigel_1 reached the box";
  EXPECT_LT(wall_front, 2.005) << "nigel_1 went into the box";
  EXPECT_LT(wall_speed, 0.02) << "nigel_1 stands at the box";
  EXPECT_LT(min_gap, 0.01) << "the two cars met";
  EXPECT_GT(min_gap, -0.01) << "a car went into the other";
  EXPECT_EQ(sim.Stop(), 0);
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

// A controller named on the command line for a mode that waits for none is refused, not
// silently ignored.
TEST_F(SimProcess, AControllerOutsideLockstepIsRefused) {
  ChildProcess p(
      {"/bin/sh", "-c", "exec \"$0\" --city \"$1\" --partition \"$2\" --controller driver 2>&1",
       Bin("autodrive-sim"), WriteCity(), partition_},
      {});
  std::string text;
  while (auto line = p.ReadLine(std::chrono::milliseconds(60000))) text += *line + "\n";
  const auto code = p.Wait(std::chrono::milliseconds(60000));
  ASSERT_TRUE(code.has_value());
  EXPECT_EQ(*code, 1) << text;
  EXPECT_NE(text.find("only lockstep waits for controllers"), std::string::npos) << text;
}

// The AprilTag library's detections (corners and centre moved to OpenCV's pixel convention:
// the library puts a pixel's centre at +0.5) by id.
std::map<int, Eigen::Vector2d> DetectTagCentres(const std::filesystem::path& png) {
  const cv::Mat gray = cv::imread(png.string(), cv::IMREAD_GRAYSCALE);
  std::map<int, Eigen::Vector2d> out;
  if (gray.empty()) return out;
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  detector->quad_decimate = 1.0f;
  image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step), gray.data};
  zarray_t* detections = apriltag_detector_detect(detector, &im);
  for (int i = 0; i < zarray_size(detections); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(detections, i, &det);
    out[det->id] = {det->c[0] - 0.5, det->c[1] - 0.5};
  }
  apriltag_detections_destroy(detections);
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  return out;
}

TEST_F(SimProcess, RenderWritesFramesWhoseTagsAreWhereTheirGroundTruthAndCalibrationSay) {
  // Two cars on the Driving School and a camera 2 m over its north-west loop.
  const std::string city = (dir_ / "city.yaml").string();
  std::ofstream(city) << "name: render_test\nmap: " << Config("config/maps/driving_school.yaml")
                      << "\nsim:\n  vehicles: [{name: nigel_1}, {name: nigel_2}]\n"
                         "  cameras:\n    - {name: top, rate_hz: 10, lens: {focal_length_mm: "
                         "1.6, width_px: 1920, height_px: 1080}, mount: {x_m: 1.5, y_m: 3.6, "
                         "z_m: 2.0, pitch_rad: 1.5708, yaw_rad: 1.5708}}\n";
  const auto out = dir_ / "set";
  const auto [code, text] = RunCaptured({Bin("autodrive-sim"), "render", "--city", city, "--camera",
                                         "top", "--duration", "1", "--out", out.string()});
  ASSERT_EQ(code, 0) << text;
  // 0, 0.1, ... 1.0 s: eleven frames.
  for (int k = 0; k <= 10; ++k) {
    EXPECT_TRUE(std::filesystem::exists(out / fmt::format("frame_{:06d}.png", k))) << k;
  }
  EXPECT_FALSE(std::filesystem::exists(out / "frame_000011.png"));
  // What an outside user has: the calibration, the pose and the ground truth, as files.
  const camera::Intrinsics k = camera::LoadOpenCvCalibration(out / "camera.yaml");
  EXPECT_EQ(k.width_px, 1920);
  EXPECT_NEAR(k.fx_px, 1.6 * 1920 / 3.68, 1e-9);
  const YAML::Node pose = YAML::LoadFile((out / "camera_pose.yaml").string());
  EXPECT_EQ(pose["parent_frame"].as<std::string>(), "map");
  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) X(r, c) = pose["X_parent_optical"][r][c].as<double>();
  }
  camera::Camera cam{"top", "top", "map", camera::CameraModel(k), Eigen::Isometry3d(X)};
  std::ifstream csv(out / "ground_truth.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad");
  int rows = 0, checked = 0;
  std::map<int, std::map<int, Eigen::Vector2d>> detections;
  while (std::getline(csv, line)) {
    ++rows;
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    ASSERT_EQ(f.size(), 7u) << line;
    const int frame = std::stoi(f[0]);
    EXPECT_NEAR(std::stod(f[1]), 0.1 * frame, 0.0021) << line;
    const int id = std::stoi(f[3]);
    EXPECT_EQ(f[2], "nigel_" + std::to_string(id));  // tag id n for nigel_<n> by default
    if (frame != 0 && frame != 10) continue;
    if (!detections.contains(frame)) {
      detections[frame] = DetectTagCentres(out / fmt::format("frame_{:06d}.png", frame));
    }
    // The tag's centre at the car's roof (0.257 m, Nigel's height) lands on the detection.
    const auto px = cam.ProjectFromParent({std::stod(f[4]), std::stod(f[5]), 0.257});
    ASSERT_TRUE(px && cam.model.IsInImage(*px)) << line;
    ASSERT_TRUE(detections[frame].contains(id)) << "tag " << id << " not found in frame " << frame;
    EXPECT_LT((detections[frame][id] - *px).norm(), 0.5) << line;
    ++checked;
  }
  EXPECT_EQ(rows, 22);
  EXPECT_EQ(checked, 4);
  // The cars drove.
  EXPECT_NE(detections[0][1], detections[10][1]);
}

TEST_F(SimProcess, InRealTimeEveryCameraIsPublishedAtItsRateWithRisingStamps) {
  const std::string city = (dir_ / "city.yaml").string();
  std::ofstream(city) << "name: camera_test\nmap: " << Config("config/maps/small_town.yaml")
                      << "\nsim:\n  vehicles:\n    - {name: nigel_7, sensors: {front_camera: "
                         "{enabled: true, rate_hz: 10, lens: {width_px: 320, height_px: 180}}}}\n"
                         "  cameras: [{name: top, rate_hz: 5, lens: {width_px: 640, height_px: "
                         "360}, mount: {x_m: 2.5, y_m: 2.5, z_m: 3.0, pitch_rad: 1.5708}}]\n";
  dds::Reader<msg::Image> front(*participant_, dds::topics::FrontCamera(VehicleId(7)));
  dds::Reader<msg::Image> top(*participant_, dds::topics::OverheadCamera("top"));
  sim_ = std::make_unique<ChildProcess>(std::vector<std::string>{
      Bin("autodrive-sim"), "--city", city, "--partition", partition_, "--log-level", "warn"});
  const auto collect = [&](dds::Reader<msg::Image>& reader, std::size_t n, const char* frame,
                           std::uint32_t width) {
    std::vector<Duration> stamps;
    const auto end = std::chrono::steady_clock::now() + seconds(60);
    while (stamps.size() < n && std::chrono::steady_clock::now() < end) {
      reader.WaitForData(milliseconds(50));
      while (auto m = reader.TakeOne()) {
        EXPECT_EQ(dds::View((*m)->header.frame_id), frame);
        EXPECT_EQ((*m)->width, width);
        EXPECT_EQ((*m)->data._length, 3u * (*m)->width * (*m)->height);
        stamps.push_back(dds::FromMsg((*m)->header.stamp) - Time{});
      }
    }
    return stamps;
  };
  const auto f = collect(front, 8, "front_camera", 320);
  const auto t = collect(top, 4, "top", 640);
  ASSERT_GE(f.size(), 8u);
  ASSERT_GE(t.size(), 4u);
  for (std::size_t k = 2; k < f.size(); ++k) {
    // 0.1 s apart (a frame may be dropped on a loaded machine: then 0.2 s). The first is at
    // the first physics step (2 ms), the others exactly at multiples of 0.1 s.
    EXPECT_GT(f[k], f[k - 1]);
    EXPECT_EQ((f[k] - f[k - 1]) % milliseconds(100), Duration{0}) << k;
  }
  for (std::size_t k = 1; k < t.size(); ++k) EXPECT_GT(t[k], t[k - 1]);
}

TEST_F(SimProcess, RenderNamesTheCamerasThereAreForAnUnknownOne) {
  const auto [code, text] = RunCaptured({Bin("autodrive-sim"), "render", "--city",
                                         Config("config/cities/driving_school.yaml"), "--camera",
                                         "attic", "--out", (dir_ / "x").string()});
  EXPECT_EQ(code, 1) << text;
  EXPECT_NE(text.find("no camera \"attic\" in the city (it has nigel_1/front_camera, "
                      "nigel_1/rear_camera, nigel_2/front_camera, nigel_2/rear_camera, overhead)"),
            std::string::npos)
      << text;
}

// `record`: a driving data set of one car alone, driven along its route by the lane driver
// from the route's first lane, one labels.csv row per frame, the frames at the size asked; the
// route's end reached (else exit 1), an unknown lane refused.
TEST_F(SimProcess, RecordWritesADrivingDataSetAlongTheRoute) {
  const auto out = dir_ / "lap";
  const std::string city = Config("config/cities/driving_school.yaml");
  const auto [code, text] = RunCaptured({Bin("autodrive-sim"), "record", "--city", city, "--route",
                                         "r2c1:W>E:0,r2c3:W>E:0", "--seed", "3", "--width", "96",
                                         "--height", "54", "--out", out.string(), "--quiet"});
  ASSERT_EQ(code, 0) << text;
  std::ifstream labels(out / "labels.csv");
  std::string line;
  std::getline(labels, line);
  EXPECT_EQ(line, "frame,stamp_s,throttle,steering,speed_mps,yaw_rate_radps,x_m,y_m,yaw_rad");
  int rows = 0;
  double x = 0, y = 0, last_t = -1, min_steering = 1, max_steering = -1;
  while (std::getline(labels, line)) {
    double f = 0, t = 0, throttle = 0, steering = 0, v = 0, w = 0, yaw = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &f, &t, &throttle,
                          &steering, &v, &w, &x, &y, &yaw),
              9)
        << line;
    EXPECT_EQ(f, rows);
    EXPECT_GT(t, last_t);
    last_t = t;
    min_steering = std::min(min_steering, steering);
    max_steering = std::max(max_steering, steering);
    const auto png = out / fmt::format("frame_{:06d}.png", rows);
    ASSERT_TRUE(std::filesystem::exists(png)) << rows;
    ++rows;
  }
  // Two straight tiles and the crossing between them: 2.7 m at about 0.15 m/s, 15 frames a
  // second.
  EXPECT_GT(rows, 150);
  EXPECT_FALSE(std::filesystem::exists(out / fmt::format("frame_{:06d}.png", rows)));
  // It ends as the driver begins to stop for the route's end (x 4.0; its front 0.23 m ahead of
  // the rear axle, the stop over the last 0.3 m): the stop itself is not recorded.
  EXPECT_GT(x, 3.3);
  EXPECT_LT(x, 3.9);
  EXPECT_NEAR(y, 2.35, 0.05);
  // The perturbed car corrects: the driver's steering goes both ways.
  EXPECT_LT(min_steering, -0.05);
  EXPECT_GT(max_steering, 0.05);
  // The frames' size is the one asked (the PNG's IHDR).
  std::ifstream png(out / "frame_000000.png", std::ios::binary);
  unsigned char header[24] = {};
  png.read(reinterpret_cast<char*>(header), sizeof header);
  EXPECT_EQ((header[16] << 24) | (header[17] << 16) | (header[18] << 8) | header[19], 96);
  EXPECT_EQ((header[20] << 24) | (header[21] << 16) | (header[22] << 8) | header[23], 54);

  const auto [bad, bad_text] =
      RunCaptured({Bin("autodrive-sim"), "record", "--city", city, "--route", "r9c9:W>E:0", "--out",
                   (dir_ / "bad").string(), "--quiet"});
  EXPECT_EQ(bad, 1);
  EXPECT_NE(bad_text.find("--route: the map driving_school has no lane 'r9c9:W>E:0'"),
            std::string::npos)
      << bad_text;
  const auto [short_code, short_text] = RunCaptured(
      {Bin("autodrive-sim"), "record", "--city", city, "--route", "r2c1:W>E:0,r2c3:W>E:0",
       "--max-duration", "2", "--out", (dir_ / "short").string(), "--quiet"});
  EXPECT_EQ(short_code, 1);
  EXPECT_NE(short_text.find("the route's end was not reached in 2 s"), std::string::npos)
      << short_text;
}

}  // namespace
}  // namespace autodrive::test
