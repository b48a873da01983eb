#include "eye/localizer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eye/registration.h"
#include "eye/testing/synthetic_scene.h"

namespace autodrive::eye {
namespace {

using testing::DrawScene;
using testing::FlatTagPose;
using testing::OverheadCamera;
using testing::PlacedTag;

// Six reference tags on the floor and a camera 3 m over the middle of a 5 m square.
class LocalizerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("eye_localizer_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    camera_ = OverheadCamera(2.5, 2.5, 3.0, 700.0, 1920, 1080);
    camera::SaveOpenCvCalibration(dir_ / "camera.yaml", camera_.model.intrinsics());
    config_.cameras.push_back({"overhead", "images:" + dir_.string(),
                               (dir_ / "camera.yaml").string(), std::nullopt, 30.0, 0.0});
    for (int i = 1; i <= 2; ++i) {
      VehicleTagConfig v;
      v.name = "nigel_" + std::to_string(i);
      v.tag_id = i;
      config_.vehicles.push_back(v);
    }
    const std::vector<std::array<double, 3>> refs{{100, 0.5, 0.5}, {101, 4.5, 4.5},
                                                  {102, 4.5, 0.5}, {103, 0.5, 4.5},
                                                  {104, 1.5, 3.5}, {105, 3.5, 1.5}};
    for (const auto& [id, x, y] : refs) {
      ReferenceTagConfig r;
      r.id = static_cast<int>(id);
      r.x_m = x;
      r.y_m = y;
      config_.reference_tags.push_back(r);
      references_.push_back({"tag36h11", r.id, r.size_m, FlatTagPose(x, y, 0.0, 0.0)});
    }
    config_.registration.frames = 1;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The reference tags plus `more`, as the camera sees them.
  cv::Mat Frame(const std::vector<PlacedTag>& more, const camera::Camera* cam = nullptr) const {
    std::vector<PlacedTag> tags = references_;
    tags.insert(tags.end(), more.begin(), more.end());
    return DrawScene(cam != nullptr ? *cam : camera_, tags);
  }

  std::filesystem::path dir_;
  camera::Camera camera_ = OverheadCamera(0, 0, 1, 1, 2, 2);
  EyeConfig config_;
  std::vector<PlacedTag> references_;
};

TEST_F(LocalizerTest, RegistrationRecoversTheCameraPose) {
  Localizer localizer(config_);
  TagDetector detector(config_.detector);
  std::string why;
  const auto r = localizer.Register(0, {detector.Detect(Frame({}))}, &why);
  ASSERT_TRUE(r) << why;
  const double dp = (r->X_MC.translation() - camera_.X_PC.translation()).norm();
  const double da = Eigen::AngleAxisd(r->X_MC.linear().transpose() * camera_.X_PC.linear()).angle();
  std::cout << "[ measured ] registration from " << r->tag_ids.size() << " tags: position error "
            << dp * 1e3 << " mm, angle error " << da * 180 / kPi << " deg, " << r->rms_px
            << " px RMS\n";
  EXPECT_EQ(r->tag_ids.size(), 6u);
  EXPECT_LT(dp, 0.005);
  EXPECT_LT(da, 0.2 * kPi / 180);
  // Written and read back.
  SavePose(dir_ / "pose.yaml", "overhead", "overhead", *r);
  EXPECT_TRUE(LoadPose(dir_ / "pose.yaml").isApprox(r->X_MC, 1e-12));
}

TEST_F(LocalizerTest, RegistrationNeedsTwoReferenceTags) {
  Localizer localizer(config_);
  TagDetector detector(config_.detector);
  std::string why;
  const cv::Mat blank = DrawScene(camera_, {references_[0]});
  EXPECT_FALSE(localizer.Register(0, {detector.Detect(blank)}, &why));
  EXPECT_NE(why.find("saw 1 reference tag(s)"), std::string::npos) << why;
  EXPECT_FALSE(localizer.registered(0));
}

TEST_F(LocalizerTest, CarsAreLocalizedAndTrackedThroughTheirRegions) {
  Localizer localizer(config_);
  std::vector<EyeEvent> events;
  int regional = 0;
  for (int i = 0; i < 40; ++i) {
    const double t = i / 30.0;
    const double x = 1.0 + 0.2 * t;
    const cv::Mat image =
        Frame({{"tag36h11", 1, 0.0762, FlatTagPose(x, 2.0, 0.257, -kPi / 2)},
               {"tag36h11", 2, 0.0762, FlatTagPose(3.0, 3.0 - 0.2 * t, 0.257, kPi)}});
    const FrameDetections d = localizer.Detect(0, TimeFromSeconds(t), image);
    if (!d.full_scan) {
      ++regional;
      // Only the cars' regions were searched: a small part of the frame.
      EXPECT_LT(d.stats.pixels, 1920 * 1080 / 20);
    }
    const auto cars = localizer.Fuse(d, &events);
    if (i == 0) {
      // The first frame registers the camera; cars are measured from the next one on.
      EXPECT_TRUE(cars.empty());
      continue;
    }
    ASSERT_EQ(cars.size(), 2u) << "frame " << i;
    for (const LocalizedVehicle& car : cars) {
      const Eigen::Vector2d truth =
          car.vehicle == 0 ? Eigen::Vector2d(x, 2.0) : Eigen::Vector2d(3.0, 3.0 - 0.2 * t);
      EXPECT_LT((car.estimate.tag_centre_M - truth).norm(), 0.002) << "frame " << i;
    }
  }
  EXPECT_GT(regional, 30);
  ASSERT_GE(events.size(), 3u);
  EXPECT_EQ(events[0].kind, EyeEvent::Kind::kCameraRegistered);
  EXPECT_EQ(events[1].kind, EyeEvent::Kind::kVehicleFound);
}

TEST_F(LocalizerTest, NoPoseFromFramesWithoutCarTagsWithDamagedTagsOrUnknownIds) {
  Localizer localizer(config_);
  std::vector<EyeEvent> events;
  ASSERT_TRUE(localizer.Fuse(localizer.Detect(0, TimeFromSeconds(0), Frame({})), &events).empty());
  ASSERT_TRUE(localizer.registered(0));
  // Unknown ids where cars would be.
  const cv::Mat unknown = Frame({{"tag36h11", 7, 0.0762, FlatTagPose(1.0, 2.0, 0.257, 0.0)},
                                 {"tag36h11", 300, 0.0762, FlatTagPose(3.0, 2.0, 0.257, 0.0)}});
  FrameDetections d = localizer.Detect(0, TimeFromSeconds(0.1), unknown, true);
  EXPECT_EQ(d.unknown_tags, 2);
  EXPECT_TRUE(localizer.Fuse(d, &events).empty());
  // Damaged car tags: a third of each tag's bits painted over, or a corner torn off.
  cv::Mat damaged = Frame({{"tag36h11", 1, 0.0762, FlatTagPose(1.0, 2.0, 0.257, 0.0)},
                           {"tag36h11", 2, 0.0762, FlatTagPose(3.0, 2.0, 0.257, 0.0)}});
  const auto px1 = *camera_.ProjectFromParent({1.0, 2.0, 0.257});
  const auto px2 = *camera_.ProjectFromParent({3.0, 2.0, 0.257});
  cv::rectangle(damaged,
                cv::Rect(static_cast<int>(px1.x()) - 3, static_cast<int>(px1.y()) - 9, 10, 10),
                cv::Scalar(255), cv::FILLED);
  cv::rectangle(damaged, cv::Rect(static_cast<int>(px2.x()), static_cast<int>(px2.y()), 14, 14),
                cv::Scalar(150), cv::FILLED);
  d = localizer.Detect(0, TimeFromSeconds(0.2), damaged, true);
  EXPECT_TRUE(d.vehicles.empty());
  EXPECT_TRUE(localizer.Fuse(d, &events).empty());
  // Nothing but floor, and noise.
  cv::Mat noise(1080, 1920, CV_8UC1);
  cv::randu(noise, 0, 256);
  for (const cv::Mat& image : {cv::Mat(1080, 1920, CV_8UC1, cv::Scalar(150)), noise}) {
    d = localizer.Detect(0, TimeFromSeconds(0.3), image, true);
    EXPECT_TRUE(d.tags.empty());
    EXPECT_TRUE(localizer.Fuse(d, &events).empty());
  }
  EXPECT_TRUE(localizer.Estimates(TimeFromSeconds(0.3)).empty());
}

TEST_F(LocalizerTest, ARealPhotoWithMarkersIsProcessedWithoutError) {
  // OpenCV's sample photo of an ArUco board (Debian's opencv-doc): real lighting, real blur,
  // square markers that are not AprilTags of our family.
  const std::filesystem::path photo = "/usr/share/doc/opencv-doc/examples/data/board.jpg";
  ASSERT_TRUE(std::filesystem::exists(photo)) << "install Debian's opencv-doc";
  const cv::Mat image = cv::imread(photo.string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty());
  TagDetector detector(config_.detector);
  DetectionStats stats;
  const auto found = detector.Detect(image, &stats);
  std::cout << "[ measured ] board.jpg (" << image.cols << "x" << image.rows
            << "): " << found.size() << " tags accepted, " << stats.refused << " refused\n";
  for (const TagDetection& d : found) {
    EXPECT_FALSE(d.id == 1 || d.id == 2) << "a car's tag in a photo of ArUco markers";
  }
}

TEST_F(LocalizerTest, ACameraTurnedByOneDegreeRaisesTheCameraMovedEvent) {
  config_.tracking.full_scan_period_s = 0.0;  // every frame a full scan (a check)
  Localizer localizer(config_);
  std::vector<EyeEvent> events;
  const auto has_moved = [&] {
    return std::any_of(events.begin(), events.end(),
                       [](const EyeEvent& e) { return e.kind == EyeEvent::Kind::kCameraMoved; });
  };
  int frame = 0;
  const auto step = [&](const camera::Camera& cam) {
    localizer.Fuse(localizer.Detect(0, TimeFromSeconds(frame / 30.0), Frame({}, &cam)), &events);
    ++frame;
  };
  for (int i = 0; i < 5; ++i) step(camera_);
  EXPECT_TRUE(localizer.registered(0));
  EXPECT_FALSE(has_moved());
  camera::Camera turned = camera_;
  turned.X_PC = camera_.X_PC * Eigen::AngleAxisd(kPi / 180, Eigen::Vector3d::UnitX());
  for (int i = 0; i < config_.registration.moved_after_checks; ++i) step(turned);
  EXPECT_TRUE(has_moved());
}

// Cameras whose poses are configured (no reference tags needed in their frames): 960 x 540,
// f 700 px, 3 m up, straight down; a roof tag is about 19 px wide.
class RegisteredCamerasTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("eye_registered_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // A camera over (x, 2.5) named `name`, added to the configuration.
  camera::Camera AddCamera(const std::string& name, double x) {
    camera::Camera cam = OverheadCamera(x, 2.5, 3.0, 700.0, 960, 540);
    const auto calibration = dir_ / (name + ".yaml");
    const auto pose = dir_ / (name + "_pose.yaml");
    camera::SaveOpenCvCalibration(calibration, cam.model.intrinsics());
    Registration r;
    r.X_MC = cam.X_PC;
    SavePose(pose, name, name, r);
    config_.cameras.push_back(
        {name, "images:" + dir_.string(), calibration.string(), pose.string(), 30.0, 0.0});
    return cam;
  }
  void AddCar(double tag_yaw_deg = 0.0) {
    VehicleTagConfig v;
    v.name = "nigel_1";
    v.tag_id = 1;
    v.mount.yaw_deg = tag_yaw_deg;
    config_.vehicles.push_back(v);
  }

  std::filesystem::path dir_;
  EyeConfig config_;
};

// nigel_1 drives east along y = 2 at 0.2 m/s from x = 1, its tag mounted as configured
// (default). Its tag's centre at time t.
Eigen::Vector2d CarTag(double t) { return {1.0 + 0.07077 + 0.2 * t, 2.0}; }
PlacedTag CarTagAt(double t) {
  return {"tag36h11", 1, 0.0762, FlatTagPose(CarTag(t).x(), CarTag(t).y(), 0.257, -kPi / 2)};
}

// Runs the frames of one camera for `seconds`, with a second tag with id 1 at `impostor` while
// `shown(t)`; the largest position error of nigel_1's rows and the events.
struct DuplicateRun {
  int rows = 0;
  double max_error_m = 0.0;
  std::optional<double> first_row_s;
  std::vector<EyeEvent> events;
};
DuplicateRun RunWithImpostor(const EyeConfig& config, const camera::Camera& cam, double seconds,
                             const Eigen::Vector2d& impostor,
                             const std::function<bool(double)>& shown) {
  Localizer localizer(config);
  DuplicateRun run;
  for (int i = 0; i < static_cast<int>(seconds * 30); ++i) {
    const double t = i / 30.0;
    std::vector<PlacedTag> tags{CarTagAt(t)};
    if (shown(t)) {
      tags.push_back({"tag36h11", 1, 0.0762, FlatTagPose(impostor.x(), impostor.y(), 0.257, 0.3)});
    }
    for (const LocalizedVehicle& car :
         localizer.LocalizeFrame(0, TimeFromSeconds(t), DrawScene(cam, tags), &run.events)) {
      ++run.rows;
      if (!run.first_row_s) run.first_row_s = t;
      run.max_error_m = std::max(run.max_error_m, (car.estimate.tag_centre_M - CarTag(t)).norm());
    }
  }
  return run;
}

int Count(const std::vector<EyeEvent>& events, EyeEvent::Kind kind, bool cleared) {
  return static_cast<int>(std::count_if(events.begin(), events.end(), [&](const EyeEvent& e) {
    return e.kind == kind && e.cleared == cleared;
  }));
}

TEST_F(RegisteredCamerasTest, ASecondTagWithACarsIdNeverStartsOrMovesItsTrackAndIsReported) {
  const camera::Camera cam = AddCamera("overhead", 2.5);
  AddCar();
  const Eigen::Vector2d impostor(3.8, 3.0);  // at the roof's height, 2.9 m from the car
  // Without the other tag: the reference.
  const DuplicateRun plain =
      RunWithImpostor(config_, cam, 8.0, impostor, [](double) { return false; });
  // With it at the start of the track (the first half second) and mid-track (4.5 s to 6.5 s).
  const DuplicateRun doubled = RunWithImpostor(
      config_, cam, 8.0, impostor, [](double t) { return t < 0.5 || (t >= 4.5 && t < 6.5); });
  std::cout << "[ measured ] without the other tag: " << plain.rows << " rows, largest error "
            << plain.max_error_m * 1e3 << " mm; with it: " << doubled.rows
            << " rows, largest error " << doubled.max_error_m * 1e3 << " mm\n";
  for (const EyeEvent& e : doubled.events) {
    std::cout << "  " << ToSeconds(e.stamp) << " s " << ToString(e.kind)
              << (e.cleared ? " (cleared) " : " ") << e.subject << ": " << e.text << "\n";
  }
  EXPECT_EQ(plain.rows, 240);
  EXPECT_LT(plain.max_error_m, 0.002);
  // Never at the other tag: every row is as close to the car as without it.
  EXPECT_LT(doubled.max_error_m, plain.max_error_m + 0.0005);
  // The track did not start while both were seen, nor before the episode ended
  // (DuplicateCheck::kClearAfter after the last time both were seen).
  const auto cleared = std::find_if(
      doubled.events.begin(), doubled.events.end(),
      [](const EyeEvent& e) { return e.kind == EyeEvent::Kind::kDuplicateTag && e.cleared; });
  ASSERT_NE(cleared, doubled.events.end());
  EXPECT_GE(ToSeconds(cleared->stamp), ToSeconds(DuplicateCheck::kClearAfter));
  ASSERT_TRUE(doubled.first_row_s.has_value());
  EXPECT_GT(*doubled.first_row_s, ToSeconds(cleared->stamp));
  // Mid-track the full scans that see both lose the car for that frame only.
  EXPECT_GT(doubled.rows, 240 - 120 - 10);
  // Once per episode: raised at the start and mid-track, cleared after the first.
  EXPECT_EQ(Count(doubled.events, EyeEvent::Kind::kDuplicateTag, false), 2);
  EXPECT_GE(Count(doubled.events, EyeEvent::Kind::kDuplicateTag, true), 1);
  EXPECT_EQ(Count(plain.events, EyeEvent::Kind::kDuplicateTag, false), 0);
  const auto raised =
      std::find_if(doubled.events.begin(), doubled.events.end(),
                   [](const EyeEvent& e) { return e.kind == EyeEvent::Kind::kDuplicateTag; });
  ASSERT_NE(raised, doubled.events.end());
  EXPECT_EQ(raised->subject, "nigel_1");
  EXPECT_NE(raised->text.find("2 tags with id 1 in one frame of camera overhead, at ("),
            std::string::npos)
      << raised->text;
  EXPECT_NE(raised->text.find("(3.80, 3.00)"), std::string::npos) << raised->text;
  EXPECT_NE(raised->text.find("remove or cover the other tag"), std::string::npos);
  EXPECT_EQ(Count(doubled.events, EyeEvent::Kind::kTagMounting, false), 0);
}

TEST_F(RegisteredCamerasTest, TwoCamerasSeeingTheIdAtTwoPlacesAtOnceRefuseBothAndTakeBackTheFirst) {
  // West sees x < 3.4, east x > 1.6: the car (x about 1.1) only in the west, the other tag
  // (x 4.8) only in the east.
  const camera::Camera west = AddCamera("west", 1.5);
  const camera::Camera east = AddCamera("east", 3.5);
  AddCar();
  Localizer localizer(config_);
  std::vector<EyeEvent> events;
  int conflicts = 0, rows = 0;
  for (int i = 0; i < 60; ++i) {
    const double t = i / 30.0;
    const Time stamp = TimeFromSeconds(t);
    std::vector<PlacedTag> east_tags;
    if (i >= 30) east_tags.push_back({"tag36h11", 1, 0.0762, FlatTagPose(4.8, 2.2, 0.257, 0.0)});
    std::vector<std::size_t> withdrawn;
    const auto from_west =
        localizer.LocalizeFrame(0, stamp, DrawScene(west, {CarTagAt(t)}), &events, &withdrawn);
    EXPECT_TRUE(withdrawn.empty());
    const auto from_east =
        localizer.LocalizeFrame(1, stamp, DrawScene(east, east_tags), &events, &withdrawn);
    EXPECT_TRUE(from_east.empty());  // the other tag is never a pose of the car
    if (!withdrawn.empty()) {
      ++conflicts;
      EXPECT_EQ(withdrawn, std::vector<std::size_t>{0});
      ASSERT_EQ(from_west.size(), 1u);  // the west's pose of this instant is taken back
      // The track is where it was before the west's frame: its last update is older.
      const auto estimates = localizer.Estimates(stamp);
      ASSERT_EQ(estimates.size(), 1u);
      EXPECT_GT(estimates[0].estimate.covariance(0, 0), from_west[0].estimate.covariance(0, 0));
    } else {
      rows += static_cast<int>(from_west.size());
    }
    for (const LocalizedVehicle& car : from_west) {
      EXPECT_LT((car.estimate.tag_centre_M - CarTag(t)).norm(), 0.003) << t;
    }
  }
  EXPECT_GE(conflicts, 1);  // the east's full scans see the other tag
  EXPECT_GT(rows, 50);
  EXPECT_EQ(Count(events, EyeEvent::Kind::kDuplicateTag, false), 1);
  const auto raised = std::find_if(events.begin(), events.end(), [](const EyeEvent& e) {
    return e.kind == EyeEvent::Kind::kDuplicateTag;
  });
  ASSERT_NE(raised, events.end());
  EXPECT_NE(raised->text.find("in camera west and at (4.80, 2.20) m in camera east"),
            std::string::npos)
      << raised->text;
  EXPECT_EQ(localizer.counters().duplicate_refusals, 2 * conflicts);
}

TEST_F(RegisteredCamerasTest, ATagTurnedFromItsConfiguredMountingRaisesTheEventWithTheTurn) {
  const camera::Camera cam = AddCamera("overhead", 2.5);
  for (const double configured : {0.0, 90.0}) {
    config_.vehicles.clear();
    AddCar(configured);
    Localizer localizer(config_);
    std::vector<EyeEvent> events;
    int rows = 0;
    for (int i = 0; i < 75; ++i) {
      const double t = i / 30.0;
      // Turned 90° on the roof: its top to the car's left, the car drives along its +x.
      const PlacedTag tag{"tag36h11", 1, 0.0762,
                          FlatTagPose(CarTag(t).x(), CarTag(t).y(), 0.257, 0.0)};
      rows += static_cast<int>(
          localizer.LocalizeFrame(0, TimeFromSeconds(t), DrawScene(cam, {tag}), &events).size());
    }
    const auto raised = std::find_if(events.begin(), events.end(), [](const EyeEvent& e) {
      return e.kind == EyeEvent::Kind::kTagMounting;
    });
    if (configured == 90.0) {
      EXPECT_EQ(raised, events.end()) << raised->text;
      EXPECT_EQ(rows, 75);
      continue;
    }
    std::cout << "[ measured ] not configured: " << rows << " of 75 frames localised\n";
    ASSERT_NE(raised, events.end());
    std::cout << "  " << ToSeconds(raised->stamp) << " s: " << raised->text << "\n";
    EXPECT_LE(ToSeconds(raised->stamp), 2.0);
    EXPECT_EQ(raised->subject, "nigel_1");
    EXPECT_NE(raised->text.find("measurements refused; its tag looks turned 9"), std::string::npos)
        << raised->text;
    EXPECT_NE(raised->text.find("° counter-clockwise from the configured mounting (the tag's "
                                "heading differs from the car's motion by 8"),
              std::string::npos)
        << raised->text;
    EXPECT_NE(raised->text.find("check tag_yaw_deg (about 9"), std::string::npos) << raised->text;
    EXPECT_EQ(Count(events, EyeEvent::Kind::kTagMounting, false), 1);
  }
}

}  // namespace
}  // namespace autodrive::eye
