#include "common/camera/camera_model.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "common/error.h"
#include "common/geometry.h"
#include "common/test_support.h"

namespace autodrive::camera {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kDeg = kPi / 180.0;

// --- Models under test ---

// A calibrated-looking PiCamera: focal lengths and principal point off the ideal values.
Intrinsics CalibratedBase() {
  Intrinsics in = PiCameraV21Intrinsics();
  in.fx_px = 1050.25;
  in.fy_px = 1052.75;
  in.cx_px = 642.3;
  in.cy_px = 356.8;
  return in;
}

struct NamedIntrinsics {
  std::string name;
  Intrinsics intrinsics;
};

// No distortion, the four- and five-coefficient model of a real lens, and a rational one.
std::vector<NamedIntrinsics> ModelsUnderTest() {
  std::vector<NamedIntrinsics> out;
  out.push_back({"none (PiCamera preset)", PiCameraV21Intrinsics()});
  Intrinsics four = CalibratedBase();
  four.distortion = {-0.28, 0.07, 0.001, -0.0005};
  out.push_back({"k1 k2 p1 p2", four});
  Intrinsics five = CalibratedBase();
  five.distortion = {-0.28, 0.07, 0.001, -0.0005, 0.0};
  out.push_back({"k1 k2 p1 p2 k3", five});
  Intrinsics rational = CalibratedBase();
  rational.distortion = {1.8, 0.6, 0.0008, -0.0004, 0.02, 2.1, 1.1, 0.1};
  out.push_back({"rational", rational});
  return out;
}

cv::Mat CvCameraMatrix(const Intrinsics& in) {
  return (cv::Mat_<double>(3, 3) << in.fx_px, 0.0, in.cx_px, 0.0, in.fy_px, in.cy_px, 0.0, 0.0,
          1.0);
}

// A column vector of doubles.
cv::Mat Column(const std::vector<double>& values) {
  cv::Mat m(static_cast<int>(values.size()), 1, CV_64F);
  for (std::size_t i = 0; i < values.size(); ++i) {
    m.at<double>(static_cast<int>(i)) = values[i];
  }
  return m;
}

cv::Mat CvDistortion(const Intrinsics& in) { return Column(in.distortion); }

// OpenCV's converged undistortion of `pixels` to normalised coordinates.
std::vector<cv::Point2d> CvUndistort(const Intrinsics& in, const std::vector<cv::Point2d>& pixels) {
  std::vector<cv::Point2d> xy;
  cv::undistortPoints(
      pixels, xy, CvCameraMatrix(in), CvDistortion(in), cv::noArray(), cv::noArray(),
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 500, 1e-13));
  return xy;
}

// Points in the optical frame: a grid of normalised coordinates reaching past every image edge
// (undistorted |x| <= 0.8, |y| <= 0.5; the image's edges are at |x| ~ 0.6-0.8, |y| ~ 0.34-0.4)
// at several depths; seeded random points in the same volume; and the points seen at the
// image's border (every 8 pixels along each edge, and the corners), placed with OpenCV's
// undistortion, at the same depths.
std::vector<Eigen::Vector3d> TestPoints(const Intrinsics& in) {
  const std::vector<double> depths = {0.05, 0.3, 1.0, 4.0, 25.0};
  std::vector<Eigen::Vector3d> points;
  for (const double z : depths) {
    for (int i = 0; i <= 32; ++i) {
      for (int j = 0; j <= 20; ++j) {
        const double x = -0.8 + 1.6 * i / 32.0;
        const double y = -0.5 + 1.0 * j / 20.0;
        points.emplace_back(x * z, y * z, z);
      }
    }
  }
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> ux(-0.8, 0.8);
  std::uniform_real_distribution<double> uy(-0.5, 0.5);
  std::uniform_real_distribution<double> uz(0.05, 30.0);
  const int n = 2000 * test::SoakFactor();
  for (int i = 0; i < n; ++i) {
    const double z = uz(rng);
    points.emplace_back(ux(rng) * z, uy(rng) * z, z);
  }
  const double right = in.width_px - 0.5;
  const double bottom = in.height_px - 0.5;
  std::vector<cv::Point2d> border;
  for (double u = -0.5; u < right; u += 8.0) {
    border.emplace_back(u, -0.5);
    border.emplace_back(u, bottom);
  }
  for (double v = -0.5; v < bottom; v += 8.0) {
    border.emplace_back(-0.5, v);
    border.emplace_back(right, v);
  }
  border.emplace_back(right, bottom);
  for (const cv::Point2d& xy : CvUndistort(in, border)) {
    for (const double z : depths) {
      points.emplace_back(xy.x * z, xy.y * z, z);
    }
  }
  return points;
}

// Pixels over the whole image: a grid every 16 pixels and the four outer corners.
std::vector<Eigen::Vector2d> TestPixels(const Intrinsics& in) {
  const double w = in.width_px;
  const double h = in.height_px;
  std::vector<Eigen::Vector2d> pixels;
  for (double u = -0.5; u <= w - 0.5; u += 16.0) {
    for (double v = -0.5; v <= h - 0.5; v += 16.0) {
      pixels.emplace_back(u, v);
    }
  }
  for (const double u : {-0.5, w - 0.5}) {
    for (const double v : {-0.5, h - 0.5}) {
      pixels.emplace_back(u, v);
    }
  }
  return pixels;
}

double DistanceToNearestEdge(const Intrinsics& in, const Eigen::Vector2d& p) {
  return std::min(
      {p.x() + 0.5, in.width_px - 0.5 - p.x(), p.y() + 0.5, in.height_px - 0.5 - p.y()});
}

// --- Projection against OpenCV ---

TEST(CameraModel, ProjectMatchesOpenCvProjectPoints) {
  for (const NamedIntrinsics& m : ModelsUnderTest()) {
    SCOPED_TRACE(m.name);
    const CameraModel model(m.intrinsics);
    const std::vector<Eigen::Vector3d> points = TestPoints(m.intrinsics);
    std::vector<cv::Point3d> cv_points;
    for (const Eigen::Vector3d& p : points) {
      cv_points.emplace_back(p.x(), p.y(), p.z());
    }
    std::vector<cv::Point2d> expected;
    cv::projectPoints(cv_points, cv::Mat::zeros(3, 1, CV_64F), cv::Mat::zeros(3, 1, CV_64F),
                      CvCameraMatrix(m.intrinsics), CvDistortion(m.intrinsics), expected);
    ASSERT_EQ(expected.size(), points.size());
    double max_error_px = 0.0;
    int near_edge = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const std::optional<Eigen::Vector2d> pixel = model.Project(points[i]);
      ASSERT_TRUE(pixel.has_value()) << "point " << points[i].transpose();
      const double error = (*pixel - Eigen::Vector2d(expected[i].x, expected[i].y)).norm();
      EXPECT_LT(error, 0.01) << "point " << points[i].transpose() << " ours " << pixel->transpose()
                             << " OpenCV " << expected[i];
      max_error_px = std::max(max_error_px, error);
      const double edge = DistanceToNearestEdge(m.intrinsics, *pixel);
      near_edge += (edge >= -0.01 && edge < 1.0) ? 1 : 0;
    }
    // The points must exercise the image's border, where distortion is strongest.
    EXPECT_GT(near_edge, 2000);
    std::cout << "[ measured ] " << m.name << ": " << points.size()
              << " points, max |Project - cv::projectPoints| = " << max_error_px << " px ("
              << near_edge << " on the image's border, within 1 px of an edge)\n";
  }
}

// --- Round trips and unprojection ---

TEST(CameraModel, ProjectUnprojectProjectRoundTripIsExact) {
  for (const NamedIntrinsics& m : ModelsUnderTest()) {
    SCOPED_TRACE(m.name);
    const CameraModel model(m.intrinsics);
    double max_pixel_error = 0.0;
    double max_normalized_error = 0.0;
    for (const Eigen::Vector3d& p : TestPoints(m.intrinsics)) {
      const Eigen::Vector2d pixel = model.Project(p).value();
      const std::optional<Eigen::Vector2d> xy = model.UndistortToNormalized(pixel);
      ASSERT_TRUE(xy.has_value()) << "pixel " << pixel.transpose();
      const double normalized_error = (*xy - p.head<2>() / p.z()).norm();
      EXPECT_LT(normalized_error, 1e-9) << "point " << p.transpose();
      max_normalized_error = std::max(max_normalized_error, normalized_error);

      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
      ASSERT_TRUE(ray.has_value());
      EXPECT_NEAR(ray->norm(), 1.0, 1e-15);
      const double pixel_error = (model.Project(*ray).value() - pixel).norm();
      EXPECT_LT(pixel_error, 1e-6) << "point " << p.transpose();
      max_pixel_error = std::max(max_pixel_error, pixel_error);
    }
    for (const Eigen::Vector2d& pixel : TestPixels(m.intrinsics)) {
      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
      ASSERT_TRUE(ray.has_value()) << "pixel " << pixel.transpose();
      const double pixel_error = (model.Project(*ray * 3.7).value() - pixel).norm();
      EXPECT_LT(pixel_error, 1e-6) << "pixel " << pixel.transpose();
      max_pixel_error = std::max(max_pixel_error, pixel_error);
    }
    std::cout << "[ measured ] " << m.name
              << ": max project-unproject-project error = " << max_pixel_error
              << " px, max unprojection error = " << max_normalized_error
              << " (normalised units)\n";
  }
}

TEST(CameraModel, UnprojectMatchesOpenCvUndistortPoints) {
  for (const NamedIntrinsics& m : ModelsUnderTest()) {
    SCOPED_TRACE(m.name);
    const CameraModel model(m.intrinsics);
    const std::vector<Eigen::Vector2d> pixels = TestPixels(m.intrinsics);
    std::vector<cv::Point2d> src;
    for (const Eigen::Vector2d& p : pixels) {
      src.emplace_back(p.x(), p.y());
    }
    // OpenCV iterates a fixed point; run it to convergence, and once with its default of 5
    // iterations to show what that costs.
    std::vector<cv::Point2d> converged;
    std::vector<cv::Point2d> default_iterations;
    cv::undistortPoints(
        src, converged, CvCameraMatrix(m.intrinsics), CvDistortion(m.intrinsics), cv::noArray(),
        cv::noArray(),
        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 500, 1e-13));
    cv::undistortPoints(src, default_iterations, CvCameraMatrix(m.intrinsics),
                        CvDistortion(m.intrinsics));
    double max_error = 0.0;
    double max_default_error = 0.0;
    for (std::size_t i = 0; i < pixels.size(); ++i) {
      const Eigen::Vector2d xy = model.UndistortToNormalized(pixels[i]).value();
      const double error = (xy - Eigen::Vector2d(converged[i].x, converged[i].y)).norm();
      EXPECT_LT(error, 1e-9) << "pixel " << pixels[i].transpose();
      max_error = std::max(max_error, error);
      max_default_error =
          std::max(max_default_error,
                   (xy - Eigen::Vector2d(default_iterations[i].x, default_iterations[i].y)).norm());
    }
    std::cout << "[ measured ] " << m.name
              << ": max |Unproject - cv::undistortPoints(converged)| = " << max_error
              << ", vs OpenCV's default 5 iterations " << max_default_error
              << " (normalised units)\n";
  }
}

TEST(CameraModel, ProjectRefusesPointsBehindOrOnTheImagePlane) {
  const CameraModel model(PiCameraV21Intrinsics());
  EXPECT_FALSE(model.Project({0.1, 0.1, 0.0}).has_value());
  EXPECT_FALSE(model.Project({0.0, 0.0, -1.0}).has_value());
  EXPECT_FALSE(model.Project({0.0, 0.0, kMinDepthM}).has_value());
  EXPECT_FALSE(model.Project({0.0, 0.0, 0.5 * kMinDepthM}).has_value());
  const std::optional<Eigen::Vector2d> ahead = model.Project({0.0, 0.0, 2.0 * kMinDepthM});
  ASSERT_TRUE(ahead.has_value());
  EXPECT_EQ(*ahead, Eigen::Vector2d(639.5, 359.5));
  EXPECT_THAT(test::ErrorMessage([&] {
                (void)model.Project({kNaN, 0.0, 1.0});
              }),
              HasSubstr("point must be finite"));
  EXPECT_THAT(test::ErrorMessage([&] {
                (void)model.Unproject({1.0, kNaN});
              }),
              HasSubstr("pixel must be finite"));
}

TEST(CameraModel, FoldingDistortionIsCutAtItsValidRadius) {
  // r (1 - 0.5 r^2) increases up to r = sqrt(2/3) and then folds back: a point at r = 1.2 would
  // land back inside the image, as cv::projectPoints shows.
  Intrinsics in = PiCameraV21Intrinsics();
  in.distortion = {-0.5, 0.0, 0.0, 0.0};
  const CameraModel model(in);
  EXPECT_NEAR(model.max_normalized_radius(), std::sqrt(2.0 / 3.0), 1e-12);

  std::vector<cv::Point2d> folded;
  cv::projectPoints(std::vector<cv::Point3d>{{1.2, 0.0, 1.0}}, cv::Mat::zeros(3, 1, CV_64F),
                    cv::Mat::zeros(3, 1, CV_64F), CvCameraMatrix(in), CvDistortion(in), folded);
  EXPECT_TRUE(model.IsInImage({folded[0].x, folded[0].y})) << folded[0];
  EXPECT_FALSE(model.Project({1.2, 0.0, 1.0}).has_value());
  EXPECT_TRUE(model.Project({0.8, 0.0, 1.0}).has_value());

  // The image of the valid region ends at f(r_max) = sqrt(2/3) * 2/3 = 0.544 normalised, 575 px
  // from the centre: the corners (734 px out) see no ray; a pixel inside it does.
  EXPECT_FALSE(model.Unproject({-0.5, -0.5}).has_value());
  const double inside_u = 639.5 + 0.54 * in.fx_px;
  const std::optional<Eigen::Vector3d> ray = model.Unproject({inside_u, 359.5});
  ASSERT_TRUE(ray.has_value());
  EXPECT_NEAR(model.Project(*ray).value().x(), inside_u, 1e-6);
  EXPECT_THAT(test::ErrorMessage([&] { (void)model.fov(); }), HasSubstr("valid region"));
}

TEST(CameraModel, RealLensModelsAreValidOverTheWholeImage) {
  for (const NamedIntrinsics& m : ModelsUnderTest()) {
    SCOPED_TRACE(m.name);
    const CameraModel model(m.intrinsics);
    const Eigen::Vector2d corner_xy = model.UndistortToNormalized({-0.5, -0.5}).value();
    EXPECT_GT(model.max_normalized_radius(), 1.5 * corner_xy.norm());
  }
  EXPECT_NEAR(CameraModel(PiCameraV21Intrinsics()).max_normalized_radius(),
              std::tan(kMaxRayAngleRad), 1e-9);
}

// --- Physical figures and field of view ---

TEST(Intrinsics, PiCameraPresetHasTheDocumentedFigures) {
  const Intrinsics in = PiCameraV21Intrinsics();
  EXPECT_EQ(in.width_px, 1280);
  EXPECT_EQ(in.height_px, 720);
  EXPECT_NEAR(in.fx_px, 3.04 * 1280 / 3.68, 1e-9);
  EXPECT_EQ(in.fy_px, in.fx_px);
  EXPECT_EQ(in.cx_px, 639.5);
  EXPECT_EQ(in.cy_px, 359.5);
  EXPECT_TRUE(in.distortion.empty());

  const FieldOfView fov = CameraModel(in).fov();
  const double horizontal_deg = fov.horizontal_rad / kDeg;
  // The field of view these figures give, 2 atan(3.68 / 2 / 3.04) = 62.37°, is 0.17° wider
  // than the 62.2° the Raspberry Pi documentation quotes beside them (62.2° would need
  // f = 3.049 mm or a 3.668 mm wide sensor): the preset keeps the physical figures.
  EXPECT_NEAR(fov.horizontal_rad, 2.0 * std::atan(3.68 / 2.0 / 3.04), 1e-12);
  EXPECT_NEAR(horizontal_deg, 62.37, 0.005);
  EXPECT_NEAR(horizontal_deg, 62.2, 0.2);
  EXPECT_NEAR(fov.vertical_rad, 2.0 * std::atan(360.0 / in.fy_px), 1e-12);
  std::cout << "[ measured ] PiCamera V2.1 preset: fx = " << in.fx_px
            << " px, horizontal FOV = " << horizontal_deg
            << " deg, vertical FOV = " << fov.vertical_rad / kDeg << " deg\n";
}

TEST(Intrinsics, FieldOfViewCountsBarrelDistortion) {
  // Radial-only barrel distortion, centred: the edges see wider than the pinhole would, and a
  // ray at half the horizontal FOV lands on the right edge.
  Intrinsics in = PiCameraV21Intrinsics();
  in.distortion = {-0.28, 0.07, 0.0, 0.0, 0.0};
  const CameraModel model(in);
  const FieldOfView fov = model.fov();
  EXPECT_GT(fov.horizontal_rad, CameraModel(PiCameraV21Intrinsics()).fov().horizontal_rad + kDeg);
  const Eigen::Vector2d right =
      model.Project({std::tan(fov.horizontal_rad / 2.0), 0.0, 1.0}).value();
  EXPECT_NEAR(right.x(), 1279.5, 1e-6);
  EXPECT_NEAR(right.y(), 359.5, 1e-9);
  const Eigen::Vector2d bottom =
      model.Project({0.0, std::tan(fov.vertical_rad / 2.0), 1.0}).value();
  EXPECT_NEAR(bottom.y(), 719.5, 1e-6);
}

TEST(Intrinsics, FromSensorRefusesNonPositiveFigures) {
  EXPECT_THAT(test::ErrorMessage([] { (void)IntrinsicsFromSensor(0.0, 3.68, 1280, 720); }),
              HasSubstr("focal_length_mm must be finite and positive, got 0"));
  EXPECT_THAT(test::ErrorMessage([] { (void)IntrinsicsFromSensor(3.04, -1.0, 1280, 720); }),
              HasSubstr("sensor_width_mm must be finite and positive, got -1"));
  EXPECT_THAT(test::ErrorMessage([] { (void)IntrinsicsFromSensor(3.04, 3.68, 0, 720); }),
              HasSubstr("width_px must be positive, got 0"));
  EXPECT_THAT(test::ErrorMessage([] { (void)IntrinsicsFromSensor(3.04, 3.68, 1280, -2); }),
              HasSubstr("height_px must be positive, got -2"));
}

TEST(Intrinsics, ValidateNamesTheBadField) {
  const auto message = [](const std::function<void(Intrinsics&)>& change) {
    Intrinsics in = PiCameraV21Intrinsics();
    change(in);
    return test::ErrorMessage([&] { CameraModel model(in); });
  };
  EXPECT_THAT(message([](Intrinsics& in) { in.width_px = 0; }),
              HasSubstr("width_px must be positive, got 0"));
  EXPECT_THAT(message([](Intrinsics& in) { in.height_px = -1; }),
              HasSubstr("height_px must be positive, got -1"));
  EXPECT_THAT(message([](Intrinsics& in) { in.fx_px = -3.0; }),
              HasSubstr("fx_px must be finite and positive, got -3"));
  EXPECT_THAT(message([](Intrinsics& in) { in.fy_px = 0.0; }),
              HasSubstr("fy_px must be finite and positive, got 0"));
  EXPECT_THAT(message([](Intrinsics& in) { in.cx_px = kNaN; }), HasSubstr("cx_px must be finite"));
  EXPECT_THAT(message([](Intrinsics& in) {
                in.distortion = {0.1, 0.2, 0.3};
              }),
              HasSubstr("distortion: expected 4, 5 or 8 coefficients"));
  EXPECT_THAT(message([](Intrinsics& in) { in.distortion.assign(14, 0.0); }),
              HasSubstr("14-coefficient model (thin prism and tilted sensor) is not supported"));
  EXPECT_THAT(message([](Intrinsics& in) {
                in.distortion = {0.1, kNaN, 0.0, 0.0};
              }),
              HasSubstr("distortion[1] must be finite"));
}

// --- Extrinsics ---

TEST(CameraPoseFromMount, OpticalAxesInTheBodyFrame) {
  const Eigen::Matrix3d R_BC = RotationBodyFromOptical();
  EXPECT_NEAR(R_BC.determinant(), 1.0, 1e-15);
  EXPECT_EQ(Eigen::Vector3d(R_BC.col(0)), Eigen::Vector3d(0, -1, 0));  // right = -left
  EXPECT_EQ(Eigen::Vector3d(R_BC.col(1)), Eigen::Vector3d(0, 0, -1));  // down = -up
  EXPECT_EQ(Eigen::Vector3d(R_BC.col(2)), Eigen::Vector3d(1, 0, 0));   // forward
  // ROS's camera_link -> camera_optical_frame rotation, rpy (-pi/2, 0, -pi/2).
  const Eigen::Matrix3d R_ros =
      QuaternionFromRollPitchYaw({.roll_rad = -kPi / 2, .yaw_rad = -kPi / 2}).toRotationMatrix();
  EXPECT_LT((R_ros - R_BC).norm(), 1e-15);
  // The rear camera (yaw 180°) looks along the car's -x with its right towards the car's +y.
  const Eigen::Isometry3d X_VC = CameraPoseFromMount({-0.035, 0, 0.110}, {.yaw_rad = kPi});
  EXPECT_LT((X_VC.linear().col(2) - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-15);
  EXPECT_LT((X_VC.linear().col(0) - Eigen::Vector3d(0, 1, 0)).norm(), 1e-15);
  EXPECT_THAT(test::ErrorMessage([] {
                (void)CameraPoseFromMount({0, kNaN, 0}, {});
              }),
              HasSubstr("position must be finite"));
}

Camera MapCamera(const RollPitchYaw& rpy) {
  return Camera{.name = "overhead",
                .frame_id = "overhead_optical",
                .parent_frame_id = "map",
                .model = CameraModel(PiCameraV21Intrinsics()),
                .X_PC = CameraPoseFromMount({0.0, 0.0, 2.0}, rpy)};
}

// The ray of the pixel where Q appears passes through Q.
void ExpectRayThrough(const Camera& camera, const Eigen::Vector2d& pixel,
                      const Eigen::Vector3d& p_MQ) {
  const Ray ray = camera.UnprojectToParent(pixel).value();
  EXPECT_LT((ray.origin_m - camera.X_PC.translation()).norm(), 1e-15);
  const Eigen::Vector3d to_q = p_MQ - ray.origin_m;
  EXPECT_LT((to_q.normalized() - ray.direction).norm(), 1e-12) << "pixel " << pixel.transpose();
}

TEST(Camera, TwoMetresAboveTheMapLookingStraightDown) {
  const double fx = PiCameraV21Intrinsics().fx_px;
  const Eigen::Vector3d p_MQ(0.5, 0.25, 0.0);
  {
    // Pitch 90° and yaw 90°: image top towards +y (north), image right towards +x (east). Q is
    // 2 m deep, 0.5 m to the right and 0.25 m up the image.
    const Camera camera = MapCamera({.pitch_rad = kPi / 2, .yaw_rad = kPi / 2});
    EXPECT_LT((camera.X_PC.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-15);
    const Eigen::Vector2d pixel = camera.ProjectFromParent(p_MQ).value();
    EXPECT_NEAR(pixel.x(), 639.5 + fx * 0.5 / 2.0, 1e-9);
    EXPECT_NEAR(pixel.y(), 359.5 - fx * 0.25 / 2.0, 1e-9);
    EXPECT_LT((camera.ProjectFromParent({0, 0, 0}).value() - Eigen::Vector2d(639.5, 359.5)).norm(),
              1e-9);
    ExpectRayThrough(camera, pixel, p_MQ);
  }
  {
    // Pitch 90° alone: image top towards +x, image right towards -y. Q is 0.25 m to the left
    // and 0.5 m up the image.
    const Camera camera = MapCamera({.pitch_rad = kPi / 2});
    const Eigen::Vector2d pixel = camera.ProjectFromParent(p_MQ).value();
    EXPECT_NEAR(pixel.x(), 639.5 - fx * 0.25 / 2.0, 1e-9);
    EXPECT_NEAR(pixel.y(), 359.5 - fx * 0.5 / 2.0, 1e-9);
    ExpectRayThrough(camera, pixel, p_MQ);
  }
  // A point above the camera is behind it.
  EXPECT_FALSE(MapCamera({.pitch_rad = kPi / 2}).ProjectFromParent({0.1, 0.1, 3.0}).has_value());
}

// A camera at (0, 0, h) with yaw 0 pitched down by alpha sees a ground point (x, y, 0) at
// depth z = x cos(alpha) + h sin(alpha), right x_C = -y, down y_C = h cos(alpha) - x sin(alpha)
// (its axes in the map: forward (cos a, 0, -sin a), right (0, -1, 0), down (-sin a, 0, -cos a)).
Eigen::Vector2d HandProjection(double alpha, double h, double x, double y) {
  const double fx = PiCameraV21Intrinsics().fx_px;
  const double z = x * std::cos(alpha) + h * std::sin(alpha);
  const double right = -y;
  const double down = h * std::cos(alpha) - x * std::sin(alpha);
  return {639.5 + fx * right / z, 359.5 + fx * down / z};
}

TEST(Camera, TiltedTwentyDegreesFromStraightDown) {
  const double alpha = 70.0 * kDeg;  // pitched 70° down = 20° from the vertical
  const Camera camera = MapCamera({.pitch_rad = alpha});
  // The optical axis meets the ground 2 tan(20°) = 0.728 m ahead: the principal point.
  const Eigen::Vector2d centre =
      camera.ProjectFromParent({2.0 * std::tan(20.0 * kDeg), 0, 0}).value();
  EXPECT_LT((centre - Eigen::Vector2d(639.5, 359.5)).norm(), 1e-9) << centre.transpose();
  // Q = (1, 0.3, 0): depth 2.2214 m, 0.3 m left, 0.2557 m up: pixel (496.70, 237.81).
  const Eigen::Vector3d p_MQ(1.0, 0.3, 0.0);
  const Eigen::Vector2d pixel = camera.ProjectFromParent(p_MQ).value();
  const Eigen::Vector2d expected = HandProjection(alpha, 2.0, 1.0, 0.3);
  EXPECT_LT((pixel - expected).norm(), 1e-9) << pixel.transpose() << " vs " << expected.transpose();
  EXPECT_NEAR(expected.x(), 496.70, 0.01);
  EXPECT_NEAR(expected.y(), 237.81, 0.01);
  ExpectRayThrough(camera, pixel, p_MQ);
}

TEST(Camera, TiltedTwentyDegreesBelowTheHorizon) {
  const double alpha = 20.0 * kDeg;
  const Camera camera = MapCamera({.pitch_rad = alpha});
  const Eigen::Vector2d centre = camera.ProjectFromParent({2.0 / std::tan(alpha), 0, 0}).value();
  EXPECT_LT((centre - Eigen::Vector2d(639.5, 359.5)).norm(), 1e-9) << centre.transpose();
  const Eigen::Vector3d p_MQ(4.0, -1.0, 0.0);
  const Eigen::Vector2d pixel = camera.ProjectFromParent(p_MQ).value();
  EXPECT_LT((pixel - HandProjection(alpha, 2.0, 4.0, -1.0)).norm(), 1e-9) << pixel.transpose();
  EXPECT_GT(pixel.x(), 639.5);  // y < 0 is to the right
  EXPECT_GT(pixel.y(), 359.5);  // nearer than the axis' ground point: below the centre
  ExpectRayThrough(camera, pixel, p_MQ);
}

// --- OpenCV calibration files ---

// A fresh directory per test, removed afterwards.
class CalibrationFile : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::path(::testing::TempDir()) / "camera_model_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr) << "mkdtemp " << pattern;
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  [[nodiscard]] fs::path Path(const std::string& name) const { return dir_ / name; }

  fs::path dir_;
};

Intrinsics RationalIntrinsics() { return ModelsUnderTest().back().intrinsics; }

TEST_F(CalibrationFile, SavedFileReadsBackExactlyWithOpenCv) {
  const Intrinsics in = RationalIntrinsics();
  ASSERT_EQ(in.distortion.size(), 8U);
  const fs::path path = Path("rational.yaml");
  SaveOpenCvCalibration(path, in);

  cv::FileStorage storage(path.string(), cv::FileStorage::READ);
  ASSERT_TRUE(storage.isOpened());
  EXPECT_EQ(static_cast<int>(storage["image_width"]), in.width_px);
  EXPECT_EQ(static_cast<int>(storage["image_height"]), in.height_px);
  cv::Mat K;
  cv::Mat D;
  storage["camera_matrix"] >> K;
  storage["distortion_coefficients"] >> D;
  ASSERT_EQ(K.type(), CV_64F);
  ASSERT_EQ(K.rows, 3);
  ASSERT_EQ(K.cols, 3);
  const Eigen::Matrix3d expected_K = in.CameraMatrix();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(K.at<double>(r, c), expected_K(r, c)) << "(" << r << ", " << c << ")";
    }
  }
  ASSERT_EQ(D.type(), CV_64F);
  ASSERT_EQ(D.rows, 8);
  ASSERT_EQ(D.cols, 1);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(D.at<double>(i), in.distortion[static_cast<std::size_t>(i)]) << "coefficient " << i;
  }
  // And the library reads its own file back exactly.
  EXPECT_EQ(LoadOpenCvCalibration(path), in);
}

TEST_F(CalibrationFile, ZeroDistortionIsSavedAsFiveZeros) {
  const fs::path path = Path("pinhole.yml");
  SaveOpenCvCalibration(path, PiCameraV21Intrinsics());
  const Intrinsics loaded = LoadOpenCvCalibration(path);
  EXPECT_EQ(loaded.distortion, std::vector<double>(5, 0.0));
  Intrinsics expected = PiCameraV21Intrinsics();
  expected.distortion.assign(5, 0.0);
  EXPECT_EQ(loaded, expected);
}

// Writes a file the way OpenCV's calibration sample (samples/cpp/calibration.cpp,
// saveCameraParams) does, with every key it writes.
void WriteLikeOpenCvSample(const fs::path& path, const cv::Mat& K, const cv::Mat& D) {
  cv::FileStorage storage(path.string(), cv::FileStorage::WRITE);
  ASSERT_TRUE(storage.isOpened());
  storage << "calibration_time"
          << "Tue Jun 11 10:00:00 2024";
  storage << "nframes" << 25;
  storage << "image_width" << 1280;
  storage << "image_height" << 720;
  storage << "board_width" << 9;
  storage << "board_height" << 6;
  storage << "square_size" << 0.025;
  storage.writeComment("flags: +zero_tangent_dist", false);
  storage << "flags" << 8;
  storage << "camera_matrix" << K;
  storage << "distortion_coefficients" << D;
  storage << "avg_reprojection_error" << 0.2134;
  storage << "per_view_reprojection_errors" << Column({0.2, 0.21, 0.23});
}

TEST_F(CalibrationFile, ReadsWhatOpenCvsCalibrationSampleWrites) {
  const Intrinsics base = CalibratedBase();
  for (const NamedIntrinsics& m : ModelsUnderTest()) {
    if (m.intrinsics.distortion.empty()) {
      continue;
    }
    SCOPED_TRACE(m.name);
    const fs::path path = Path("sample.yaml");
    WriteLikeOpenCvSample(path, CvCameraMatrix(m.intrinsics), CvDistortion(m.intrinsics));
    EXPECT_EQ(LoadOpenCvCalibration(path), m.intrinsics);
  }
  // A 1xN distortion row and a single-precision matrix are read too.
  Intrinsics five = base;
  five.distortion = {-0.28, 0.07, 0.001, -0.0005, 0.01};
  const fs::path path = Path("row.xml");
  cv::Mat K32;
  CvCameraMatrix(five).convertTo(K32, CV_32F);
  WriteLikeOpenCvSample(path, K32, CvDistortion(five).t());
  const Intrinsics loaded = LoadOpenCvCalibration(path);
  EXPECT_EQ(loaded.distortion, five.distortion);
  EXPECT_EQ(loaded.fx_px, static_cast<double>(static_cast<float>(five.fx_px)));
  EXPECT_EQ(loaded.cy_px, static_cast<double>(static_cast<float>(five.cy_px)));
}

// One refusal: how to write the file, and what the message must say after `FILE: `.
struct Refusal {
  std::string name;
  std::function<void(cv::FileStorage&)> write;
  std::string expected;
};

cv::Mat GoodK() { return CvCameraMatrix(CalibratedBase()); }
cv::Mat GoodD() { return Column({-0.28, 0.07, 0.001, -0.0005, 0.0}); }

cv::Mat WithK(int r, int c, double value) {
  cv::Mat K = GoodK();
  K.at<double>(r, c) = value;
  return K;
}

void WriteAll(cv::FileStorage& storage, const std::string& skip, const cv::Mat& K,
              const cv::Mat& D) {
  if (skip != "image_width") storage << "image_width" << 1280;
  if (skip != "image_height") storage << "image_height" << 720;
  if (skip != "camera_matrix") storage << "camera_matrix" << K;
  if (skip != "distortion_coefficients") storage << "distortion_coefficients" << D;
}

std::vector<Refusal> Refusals() {
  const auto with = [](const std::string& skip, const cv::Mat& K, const cv::Mat& D) {
    return [=](cv::FileStorage& storage) { WriteAll(storage, skip, K, D); };
  };
  const auto zeros = [](int rows, int cols) { return cv::Mat(cv::Mat::zeros(rows, cols, CV_64F)); };
  std::vector<Refusal> r;
  for (const std::string key :
       {"image_width", "image_height", "camera_matrix", "distortion_coefficients"}) {
    r.push_back({"missing " + key, with(key, GoodK(), GoodD()), key + ": missing required key"});
  }
  r.push_back({"zero width",
               [&](cv::FileStorage& storage) {
                 storage << "image_width" << 0;
                 WriteAll(storage, "image_width", GoodK(), GoodD());
               },
               "image_width: must be positive (got 0)"});
  r.push_back({"negative height",
               [&](cv::FileStorage& storage) {
                 storage << "image_height" << -720;
                 WriteAll(storage, "image_height", GoodK(), GoodD());
               },
               "image_height: must be positive (got -720)"});
  r.push_back({"fractional width",
               [&](cv::FileStorage& storage) {
                 storage << "image_width" << 1280.5;
                 WriteAll(storage, "image_width", GoodK(), GoodD());
               },
               "image_width: must be an integer number of pixels (got 1280.5)"});
  r.push_back({"3x4 camera matrix", with("", zeros(3, 4), GoodD()),
               "camera_matrix: must be 3x3 (got 3x4)"});
  r.push_back({"2x2 camera matrix", with("", cv::Mat(cv::Mat::eye(2, 2, CV_64F)), GoodD()),
               "camera_matrix: must be 3x3 (got 2x2)"});
  r.push_back({"camera matrix not a matrix",
               [&](cv::FileStorage& storage) {
                 storage << "camera_matrix" << 1050.0;
                 WriteAll(storage, "camera_matrix", GoodK(), GoodD());
               },
               "camera_matrix: must be an !!opencv-matrix"});
  r.push_back({"camera matrix without dt",
               [&](cv::FileStorage& storage) {
                 storage << "camera_matrix"
                         << "{"
                         << "rows" << 3 << "cols" << 3 << "data"
                         << "[";
                 for (int i = 0; i < 9; ++i) storage << 1.0;
                 storage << "]"
                         << "}";
                 WriteAll(storage, "camera_matrix", GoodK(), GoodD());
               },
               "camera_matrix: not a readable !!opencv-matrix (OpenCV: "});
  r.push_back({"zero fx", with("", WithK(0, 0, 0.0), GoodD()),
               "camera_matrix: focal length fx = element (0, 0) must be positive (got 0)"});
  r.push_back({"negative fx", with("", WithK(0, 0, -1050.0), GoodD()),
               "camera_matrix: focal length fx = element (0, 0) must be positive (got -1050)"});
  r.push_back({"negative fy", with("", WithK(1, 1, -1.5), GoodD()),
               "camera_matrix: focal length fy = element (1, 1) must be positive (got -1.5)"});
  r.push_back({"skew", with("", WithK(0, 1, 0.5), GoodD()),
               "camera_matrix: skew (element (0, 1)) is not supported"});
  r.push_back({"last row", with("", WithK(2, 2, 2.0), GoodD()),
               "camera_matrix: must have the form [fx 0 cx; 0 fy cy; 0 0 1]"});
  r.push_back({"NaN in camera matrix", with("", WithK(0, 2, kNaN), GoodD()),
               "camera_matrix: element (0, 2) must be finite"});
  for (const int n : {1, 3, 6, 7, 9}) {
    r.push_back({std::to_string(n) + " coefficients", with("", GoodK(), zeros(n, 1)),
                 "distortion_coefficients: expected 4, 5 or 8 coefficients (k1, k2, p1, p2[, "
                 "k3[, k4, k5, k6]]), got " +
                     std::to_string(n)});
  }
  r.push_back({"12 coefficients", with("", GoodK(), zeros(12, 1)),
               "distortion_coefficients: OpenCV's 12-coefficient model (thin prism) is not "
               "supported (got 12 coefficients; expected 4, 5 or 8)"});
  r.push_back({"14 coefficients", with("", GoodK(), zeros(1, 14)),
               "distortion_coefficients: OpenCV's 14-coefficient model (thin prism and tilted "
               "sensor) is not supported (got 14 coefficients; expected 4, 5 or 8)"});
  r.push_back({"2x4 distortion", with("", GoodK(), zeros(2, 4)),
               "distortion_coefficients: must be a 1xN or Nx1 vector (got 2x4)"});
  r.push_back({"NaN distortion", with("", GoodK(), Column({0.1, kNaN, 0.0, 0.0})),
               "distortion_coefficients: coefficient 1 must be finite"});
  r.push_back({"three-channel camera matrix",
               with("", cv::Mat(3, 3, CV_64FC3, cv::Scalar(1.0)), GoodD()),
               "camera_matrix: must have one channel (got 3)"});
  return r;
}

TEST_F(CalibrationFile, RefusalsNameTheFileAndTheKey) {
  for (const Refusal& refusal : Refusals()) {
    SCOPED_TRACE(refusal.name);
    const fs::path path = Path("bad.yaml");
    {
      cv::FileStorage storage(path.string(), cv::FileStorage::WRITE);
      ASSERT_TRUE(storage.isOpened());
      refusal.write(storage);
    }
    const std::string message =
        test::ErrorMessage<ConfigError>([&] { (void)LoadOpenCvCalibration(path); });
    EXPECT_THAT(message, HasSubstr(path.string() + ": " + refusal.expected));
  }
}

TEST_F(CalibrationFile, RefusesMissingAndUnparsableFiles) {
  const fs::path missing = Path("no_such.yaml");
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)LoadOpenCvCalibration(missing); }),
            missing.string() + ": cannot read camera calibration file (no such file)");
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)LoadOpenCvCalibration(dir_); }),
            dir_.string() + ": cannot read camera calibration file (not a regular file)");

  const fs::path garbage = Path("garbage.yaml");
  std::ofstream(garbage) << "%YAML:1.0\n---\nimage_width: [1280\ncamera_matrix: {{{\n";
  EXPECT_THAT(
      test::ErrorMessage<ConfigError>([&] { (void)LoadOpenCvCalibration(garbage); }),
      AllOf(HasSubstr(garbage.string() + ": cannot parse camera calibration file (OpenCV: "),
            HasSubstr(garbage.string() + "(")));  // OpenCV's line number
}

TEST_F(CalibrationFile, SaveRefusesInvalidIntrinsicsAndUnwritablePaths) {
  Intrinsics bad = PiCameraV21Intrinsics();
  bad.fx_px = 0.0;
  EXPECT_THAT(test::ErrorMessage([&] { SaveOpenCvCalibration(Path("bad.yaml"), bad); }),
              HasSubstr("fx_px must be finite and positive, got 0"));
  EXPECT_FALSE(fs::exists(Path("bad.yaml")));
  const fs::path unwritable = Path("no_such_dir") / "camera.yaml";
  EXPECT_THAT(
      test::ErrorMessage([&] { SaveOpenCvCalibration(unwritable, PiCameraV21Intrinsics()); }),
      HasSubstr(unwritable.string() + ": cannot write camera calibration file"));
}

}  // namespace
}  // namespace autodrive::camera
