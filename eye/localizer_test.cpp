#include "eye/localizer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
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

}  // namespace
}  // namespace autodrive::eye
