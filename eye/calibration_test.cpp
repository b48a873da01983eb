#include "eye/calibration.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/camera/camera_model.h"
#include "common/error.h"
#include "common/geometry.h"
#include "common/test_support.h"
#include "eye/testing/programs.h"

namespace autodrive::eye {
namespace {

namespace fs = std::filesystem;
using test::ErrorMessage;
using testing::RunProgram;

// OpenCV's sample photos of a 9x6 chessboard (Debian package opencv-doc), 640x480. The
// package ships left01..left09 and left11..left14: there is no left10.jpg.
const fs::path kOpenCvData = "/usr/share/doc/opencv-doc/examples/data";
const BoardSpec kSampleBoard{.cols = 9, .rows = 6, .square_m = 0.025};

std::vector<fs::path> SamplePhotos() {
  std::vector<fs::path> photos;
  for (int i = 1; i <= 14; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "left%02d.jpg", i);
    if (fs::exists(kOpenCvData / name)) photos.push_back(kOpenCvData / name);
  }
  return photos;
}

// The calibration of the sample photos with the default options, computed once per process.
const CalibrationResult& SampleCalibration() {
  static const CalibrationResult result = Calibrate(SamplePhotos(), kSampleBoard, {});
  return result;
}

// A directory of the test's own under the system's temporary directory, removed with
// everything in it when the object goes.
class TempDir {
 public:
  TempDir()
      : path_(fs::temp_directory_path() /
              ("autodrive_eye_calibration_test_" + std::to_string(::getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name())) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  [[nodiscard]] const fs::path& path() const { return path_; }
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// --- Synthetic views ---

// The ground-truth camera of the synthetic views.
camera::Intrinsics SyntheticIntrinsics() {
  return {.width_px = 1280,
          .height_px = 720,
          .fx_px = 900.0,
          .fy_px = 900.0,
          .cx_px = 650.0,
          .cy_px = 355.0,
          .distortion = {-0.1, 0.02, 0.0, 0.0, 0.0}};
}

const BoardSpec kSyntheticBoard{.cols = 9, .rows = 6, .square_m = 0.04};

// Renders `board` (its (cols + 1) x (rows + 1) squares, the one at the board frame's origin
// corner black, in a white margin of one square) as seen by `model` from pose X_CB, on a grey
// background. Every edge of a square is cut into short segments whose ends are projected
// through the camera model, so that edges bend with the distortion; the polygons are filled
// anti-aliased at kSupersample times the resolution and averaged down (INTER_AREA), then
// blurred by a Gaussian of sigma 0.8 px like a real lens. Precondition: the whole board is in
// front of the camera.
cv::Mat RenderChessboard(const camera::CameraModel& model, const BoardSpec& board,
                         const Eigen::Isometry3d& X_CB) {
  constexpr int kSupersample = 8;
  constexpr int kShiftBits = 8;  // fillPoly's fixed-point fraction bits
  constexpr int kSegmentsPerEdge = 8;
  const camera::Intrinsics& k = model.intrinsics();
  cv::Mat fine(k.height_px * kSupersample, k.width_px * kSupersample, CV_8U, cv::Scalar(90));
  const auto fill = [&](double x0, double y0, double x1, double y1, int grey) {
    const std::array<Eigen::Vector2d, 4> ends = {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x1, y0),
                                                 Eigen::Vector2d(x1, y1), Eigen::Vector2d(x0, y1)};
    std::vector<cv::Point> polygon;
    for (std::size_t e = 0; e < 4; ++e) {
      for (int s = 0; s < kSegmentsPerEdge; ++s) {
        const Eigen::Vector2d p_B = ends[e] + (ends[(e + 1) % 4] - ends[e]) * s / kSegmentsPerEdge;
        const std::optional<Eigen::Vector2d> uv =
            model.Project(X_CB * Eigen::Vector3d(p_B.x(), p_B.y(), 0.0));
        EXPECT_TRUE(uv.has_value());
        if (!uv) return;
        // Pixel (u, v) of the image is the centre of a kSupersample-square block of fine
        // pixels: u * kSupersample + (kSupersample - 1) / 2 in the fine image.
        const Eigen::Vector2d fine_uv = (*uv * kSupersample).array() + (kSupersample - 1) / 2.0;
        polygon.emplace_back(static_cast<int>(std::lround(fine_uv.x() * (1 << kShiftBits))),
                             static_cast<int>(std::lround(fine_uv.y() * (1 << kShiftBits))));
      }
    }
    cv::fillPoly(fine, std::vector<std::vector<cv::Point>>{polygon}, cv::Scalar(grey), cv::LINE_AA,
                 kShiftBits);
  };
  const double s = board.square_m;
  fill(-2 * s, -2 * s, (board.cols + 1) * s, (board.rows + 1) * s, 235);  // white margin
  for (int a = -1; a < board.cols; ++a) {
    for (int b = -1; b < board.rows; ++b) {
      if ((a + b) % 2 == 0) fill(a * s, b * s, (a + 1) * s, (b + 1) * s, 20);
    }
  }
  cv::Mat image;
  cv::resize(fine, image, cv::Size(k.width_px, k.height_px), 0, 0, cv::INTER_AREA);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  return image;
}

// The true pixels of the board's inner corners, row by row.
std::vector<Eigen::Vector2d> TrueCorners(const camera::CameraModel& model, const BoardSpec& board,
                                         const Eigen::Isometry3d& X_CB) {
  std::vector<Eigen::Vector2d> corners;
  for (int j = 0; j < board.rows; ++j) {
    for (int i = 0; i < board.cols; ++i) {
      const auto uv =
          model.Project(X_CB * Eigen::Vector3d(i * board.square_m, j * board.square_m, 0));
      corners.push_back(uv.value_or(Eigen::Vector2d(-1e9, -1e9)));
    }
  }
  return corners;
}

// One synthetic view: the pixel the middle of the board is seen at (without distortion), its
// distance along the optical axis, and its tilts (degrees; the board's rotation about the
// camera's x, then y, then z axis, from facing the camera square on).
struct ViewPose {
  double u_px, v_px, z_m, about_x_deg, about_y_deg, about_z_deg;
};

// Twelve views that tilt the board by up to 40 degrees and put it all over the image.
constexpr std::array<ViewPose, 12> kSyntheticPoses = {{
    {640, 360, 0.70, 0, 0, 0},
    {420, 230, 0.75, 30, -25, 10},
    {860, 230, 0.75, 30, 25, -10},
    {420, 490, 0.75, -30, -25, -5},
    {860, 490, 0.75, -30, 25, 5},
    {640, 360, 0.65, 35, 0, 90},
    {640, 360, 0.80, 0, 40, 0},
    {330, 360, 0.90, 0, -35, 20},
    {950, 360, 0.90, 0, 35, -20},
    {640, 200, 0.90, 35, 0, 0},
    {640, 520, 0.90, -35, 0, 0},
    {640, 360, 0.60, 20, 20, 45},
}};

Eigen::Isometry3d PoseOf(const ViewPose& v, const camera::Intrinsics& k, const BoardSpec& board) {
  const auto rad = [](double deg) { return deg * kPi / 180.0; };
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(rad(v.about_z_deg), Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(rad(v.about_y_deg), Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(rad(v.about_x_deg), Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d middle_B((board.cols - 1) * board.square_m / 2,
                                 (board.rows - 1) * board.square_m / 2, 0.0);
  const Eigen::Vector3d middle_C(v.z_m * (v.u_px - k.cx_px) / k.fx_px,
                                 v.z_m * (v.v_px - k.cy_px) / k.fy_px, v.z_m);
  Eigen::Isometry3d X_CB = Eigen::Isometry3d::Identity();
  X_CB.linear() = R;
  X_CB.translation() = middle_C - R * middle_B;
  return X_CB;
}

// RMS distance, px, between corners found and the true ones, in the order that matches best
// (the detectors may start from either end of a 9x6 board: it looks the same turned by 180
// degrees).
double CornerRmsError(const std::vector<Eigen::Vector2d>& found,
                      const std::vector<Eigen::Vector2d>& truth) {
  EXPECT_EQ(found.size(), truth.size());
  if (found.size() != truth.size() || found.empty()) {
    return std::numeric_limits<double>::infinity();
  }
  double forward = 0.0;
  double reversed = 0.0;
  for (std::size_t i = 0; i < found.size(); ++i) {
    forward += (found[i] - truth[i]).squaredNorm();
    reversed += (found[i] - truth[truth.size() - 1 - i]).squaredNorm();
  }
  return std::sqrt(std::min(forward, reversed) / static_cast<double>(found.size()));
}

// --- The board's text ---

TEST(BoardSpec, ParsesColsRowsAndSquareSizeAndPrintsTheSameText) {
  const BoardSpec board = ParseBoardSpec("chessboard:9x6:0.025");
  EXPECT_EQ(board, (BoardSpec{.cols = 9, .rows = 6, .square_m = 0.025}));
  EXPECT_EQ(BoardSpecText(board), "chessboard:9x6:0.025");
  EXPECT_EQ(ParseBoardSpec(BoardSpecText(board)), board);
  EXPECT_EQ(ParseBoardSpec("chessboard:7X5:1e-2"),
            (BoardSpec{.cols = 7, .rows = 5, .square_m = 0.01}));
}

TEST(BoardSpec, RefusesBadTextNamingTheBadPartAndTheExpectedForm) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"chessboard:9x6", "2 part(s) separated by ':', not 3"},
      {"chessboard:9x6:0.02:1", "4 part(s)"},
      {"chess:9x6:0.02", "unknown pattern \"chess\""},
      {"chessboard:0x6:0.02", "COLS (inner corners per row) must be at least 3, got 0"},
      {"chessboard:9x2:0.02", "ROWS (inner corners per column) must be at least 3, got 2"},
      {"chessboard:9x6:-1", "SQUARE_M (the side of a square, metres) must be > 0"},
      {"chessboard:9x6:25", "got 25 (25 mm squares are 0.025)"},
      {"chessboard:9x6:nan", "got nan"},
      {"chessboard:9by6:0.02",
       "COLSxROWS must be two whole numbers separated by 'x', got \"9by6\""},
      {"chessboard:9x:0.02", "got \"9x\""},
      {"chessboard:9x6:abc", "SQUARE_M must be a number of metres, got \"abc\""},
      {"", "1 part(s)"},
  };
  for (const auto& [text, problem] : cases) {
    const std::string message = ErrorMessage([&] { (void)ParseBoardSpec(text); });
    EXPECT_NE(message.find("bad board \"" + text + "\""), std::string::npos) << message;
    EXPECT_NE(message.find(problem), std::string::npos) << text << " -> " << message;
    EXPECT_NE(message.find("expected chessboard:COLSxROWS:SQUARE_M"), std::string::npos) << message;
  }
  EXPECT_NE(ErrorMessage([] {
              BoardSpec{.cols = 9, .rows = 6, .square_m = 0}.Validate();
            }).find("must be > 0 and <= 1, got 0"),
            std::string::npos);
}

TEST(CalibrationOptions, RefusesADistortionModelOtherThan4Or5Or8) {
  for (const int n : {4, 5, 8}) {
    EXPECT_NO_THROW(CalibrationOptions{.distortion_coefficients = n}.Validate());
  }
  EXPECT_NE(ErrorMessage([] {
              CalibrationOptions{.distortion_coefficients = 6}.Validate();
            }).find("distortion_coefficients must be 4, 5 or 8 (OpenCV's rational model), got 6"),
            std::string::npos);
}

// --- OpenCV's sample photos ---

TEST(Calibrate, OpenCvSamplePhotosFindEveryBoardWithRmsUnderHalfAPixel) {
  const std::vector<fs::path> photos = SamplePhotos();
  ASSERT_GE(photos.size(), 13u) << "OpenCV's sample photos are missing from " << kOpenCvData
                                << " (install the Debian package opencv-doc)";
  const CalibrationResult& result = SampleCalibration();
  ASSERT_EQ(result.views.size(), photos.size());
  // Every sample photo shows the whole board, sharp enough (left02's squares are the smallest,
  // about 20 px).
  EXPECT_EQ(result.used_views(), photos.size());
  double worst_view_px = 0.0;
  std::string worst_view;
  for (const CalibrationView& view : result.views) {
    EXPECT_EQ(view.status, ViewStatus::kUsed) << view.image << ": " << view.problem;
    EXPECT_TRUE(view.problem.empty());
    EXPECT_EQ(view.corners_px.size(), 54u);
    ASSERT_TRUE(view.rms_error_px.has_value()) << view.image;
    ASSERT_TRUE(view.X_CB.has_value()) << view.image;
    EXPECT_LT(*view.rms_error_px, 0.5) << view.image;
    if (*view.rms_error_px > worst_view_px) {
      worst_view_px = *view.rms_error_px;
      worst_view = view.image.filename().string();
    }
    // The board is in front of the camera, some 30-50 cm away (its squares are 25 mm).
    EXPECT_GT(view.X_CB->translation().z(), 0.1) << view.image;
  }
  EXPECT_LT(result.rms_error_px, 0.5);
  const camera::Intrinsics& k = result.intrinsics;
  EXPECT_EQ(k.width_px, 640);
  EXPECT_EQ(k.height_px, 480);
  EXPECT_EQ(k.distortion.size(), 5u);

  // Cross-check with OpenCV's own calibration of the same photos, shipped beside them
  // (left_intrinsics.yml: its sample program, fx = fy fixed, the classic detector with an 11 px
  // half-window, RMS 0.39 px) and read with the project's loader.
  const camera::Intrinsics reference =
      camera::LoadOpenCvCalibration(kOpenCvData / "left_intrinsics.yml");
  EXPECT_NEAR(k.fx_px / reference.fx_px, 1.0, 0.01);
  EXPECT_NEAR(k.fy_px / reference.fy_px, 1.0, 0.01);
  EXPECT_NEAR(k.cx_px, reference.cx_px, 3.0);
  EXPECT_NEAR(k.cy_px, reference.cy_px, 3.0);
  EXPECT_NEAR(k.distortion[0], reference.distortion[0], 0.03);  // k1, about -0.27

  // The overall RMS is that of every corner: each view has 54, so rms^2 = mean(view rms^2).
  double sum_sq = 0.0;
  for (const CalibrationView& view : result.views)
    sum_sq += *view.rms_error_px * *view.rms_error_px;
  EXPECT_NEAR(result.rms_error_px, std::sqrt(sum_sq / static_cast<double>(result.views.size())),
              1e-9);
  EXPECT_GT(result.std_dev.fx_px, 0.0);
  EXPECT_LT(result.std_dev.fx_px, 2.0);

  std::printf(
      "[ measured ] OpenCV sample photos: %zu of %zu boards found; RMS %.4f px (worst view %s "
      "%.3f px); fx %.2f fy %.2f cx %.2f cy %.2f px (std dev fx %.2f); k1 %.4f k2 %.4f; "
      "OpenCV's left_intrinsics.yml: fx %.2f cx %.2f cy %.2f\n",
      result.used_views(), result.views.size(), result.rms_error_px, worst_view.c_str(),
      worst_view_px, k.fx_px, k.fy_px, k.cx_px, k.cy_px, result.std_dev.fx_px, k.distortion[0],
      k.distortion[1], reference.fx_px, reference.cx_px, reference.cy_px);
}

TEST(Calibrate, ReportsEachPhotoToTheProgressCallbackInOrder) {
  const std::vector<fs::path> photos = SamplePhotos();
  ASSERT_GE(photos.size(), 3u);
  const std::vector<fs::path> three(photos.begin(), photos.begin() + 3);
  std::vector<std::pair<fs::path, std::size_t>> seen;
  const CalibrationResult result =
      Calibrate(three, kSampleBoard, {},
                [&](const CalibrationView& view, std::size_t index, std::size_t count) {
                  EXPECT_EQ(count, 3u);
                  EXPECT_EQ(view.status, ViewStatus::kUsed);
                  EXPECT_FALSE(view.rms_error_px.has_value());  // not calibrated yet
                  seen.emplace_back(view.image, index);
                });
  ASSERT_EQ(seen.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(seen[i].first, three[i]);
    EXPECT_EQ(seen[i].second, i);
  }
  EXPECT_EQ(result.used_views(), 3u);
}

TEST(Calibrate, DistortionModelsAndFixedParametersFollowTheOptions) {
  const std::vector<fs::path> photos = SamplePhotos();
  const CalibrationResult four = Calibrate(photos, kSampleBoard, {.distortion_coefficients = 4});
  EXPECT_EQ(four.intrinsics.distortion.size(), 4u);
  EXPECT_EQ(four.std_dev.distortion.size(), 4u);
  const CalibrationResult eight = Calibrate(photos, kSampleBoard, {.distortion_coefficients = 8});
  EXPECT_EQ(eight.intrinsics.distortion.size(), 8u);
  // More coefficients fit at least as well.
  EXPECT_LE(eight.rms_error_px, SampleCalibration().rms_error_px + 1e-6);
  EXPECT_LE(SampleCalibration().rms_error_px, four.rms_error_px + 1e-6);
  EXPECT_LT(eight.rms_error_px, 0.5);

  // OpenCV keeps a fixed principal point at its initial guess, the image centre in the camera
  // model's pixel convention.
  const CalibrationResult centred =
      Calibrate(photos, kSampleBoard, {.fix_principal_point = true, .fix_aspect_ratio = true});
  EXPECT_EQ(centred.intrinsics.cx_px, (640 - 1) / 2.0);
  EXPECT_EQ(centred.intrinsics.cy_px, (480 - 1) / 2.0);
  EXPECT_EQ(centred.intrinsics.fx_px, centred.intrinsics.fy_px);
  EXPECT_LT(centred.rms_error_px, 0.5);
  std::printf(
      "[ measured ] sample photos, RMS px: 4 coefficients %.4f, 5 %.4f, 8 %.4f, principal point "
      "fixed at the centre and fx = fy %.4f\n",
      four.rms_error_px, SampleCalibration().rms_error_px, eight.rms_error_px,
      centred.rms_error_px);
}

// Blurred photos (a lens out of focus, motion): the classic detector gives up on most, the
// sector-based one that Calibrate falls back to finds them.
TEST(Calibrate, FindsBoardsInBlurredPhotosThatTheClassicDetectorMisses) {
  const TempDir dir;
  std::vector<fs::path> blurred;
  int classic_found = 0;
  for (const fs::path& photo : SamplePhotos()) {
    cv::Mat grey = cv::imread(photo.string(), cv::IMREAD_GRAYSCALE);
    cv::GaussianBlur(grey, grey, cv::Size(0, 0), 4.5);
    std::vector<cv::Point2f> corners;
    classic_found +=
        cv::findChessboardCorners(
            grey, cv::Size(9, 6), corners,
            cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK)
            ? 1
            : 0;
    blurred.push_back(dir / photo.filename().replace_extension(".png"));
    ASSERT_TRUE(cv::imwrite(blurred.back().string(), grey));
  }
  ASSERT_GE(blurred.size(), 13u);
  // The precondition of this test: the classic detector alone would not do.
  ASSERT_LT(classic_found + static_cast<int>(kMinCalibrationViews),
            static_cast<int>(blurred.size()));
  const CalibrationResult result = Calibrate(blurred, kSampleBoard, {});
  EXPECT_EQ(result.used_views(), blurred.size());
  EXPECT_LT(result.rms_error_px, 0.5);
  const camera::Intrinsics& sharp = SampleCalibration().intrinsics;
  EXPECT_NEAR(result.intrinsics.fx_px / sharp.fx_px, 1.0, 0.02);
  EXPECT_NEAR(result.intrinsics.cx_px, sharp.cx_px, 5.0);
  EXPECT_NEAR(result.intrinsics.cy_px, sharp.cy_px, 5.0);
  std::printf(
      "[ measured ] sample photos blurred by sigma 4.5 px: the classic detector finds %d of "
      "%zu boards, Calibrate %zu; RMS %.4f px; fx %.2f cx %.2f cy %.2f px (sharp: fx %.2f cx "
      "%.2f cy %.2f)\n",
      classic_found, blurred.size(), result.used_views(), result.rms_error_px,
      result.intrinsics.fx_px, result.intrinsics.cx_px, result.intrinsics.cy_px, sharp.fx_px,
      sharp.cx_px, sharp.cy_px);
}

// --- Synthetic views of a known camera ---

TEST(Calibrate, RecoversAKnownCameraFromSyntheticViews) {
  const TempDir dir;
  const camera::CameraModel truth(SyntheticIntrinsics());
  std::vector<Eigen::Isometry3d> poses;
  std::vector<std::vector<Eigen::Vector2d>> true_corners;
  for (std::size_t v = 0; v < kSyntheticPoses.size(); ++v) {
    poses.push_back(PoseOf(kSyntheticPoses[v], truth.intrinsics(), kSyntheticBoard));
    true_corners.push_back(TrueCorners(truth, kSyntheticBoard, poses.back()));
    // Guard on the table of poses: every corner well inside the image.
    for (const Eigen::Vector2d& c : true_corners.back()) {
      ASSERT_TRUE(c.x() > 30 && c.x() < 1250 && c.y() > 30 && c.y() < 690)
          << "view " << v << " puts a corner at " << c.transpose();
    }
    char name[32];
    std::snprintf(name, sizeof name, "view_%02zu.png", v);
    ASSERT_TRUE(
        cv::imwrite((dir / name).string(), RenderChessboard(truth, kSyntheticBoard, poses.back())));
  }
  const std::vector<fs::path> images = ListCalibrationImages(dir.path());
  ASSERT_EQ(images.size(), kSyntheticPoses.size());
  const CalibrationResult result = Calibrate(images, kSyntheticBoard, {});
  ASSERT_EQ(result.used_views(), kSyntheticPoses.size());

  double worst_corner_px = 0.0;
  double worst_middle_m = 0.0;
  const Eigen::Vector3d middle_B((kSyntheticBoard.cols - 1) * kSyntheticBoard.square_m / 2,
                                 (kSyntheticBoard.rows - 1) * kSyntheticBoard.square_m / 2, 0.0);
  for (std::size_t v = 0; v < result.views.size(); ++v) {
    const CalibrationView& view = result.views[v];
    const double corner_px = CornerRmsError(view.corners_px, true_corners[v]);
    EXPECT_LT(corner_px, 0.1) << view.image;
    worst_corner_px = std::max(worst_corner_px, corner_px);
    // The board's middle is where it was put (the same point whichever corner the detector
    // started from).
    const double middle_m = (*view.X_CB * middle_B - poses[v] * middle_B).norm();
    EXPECT_LT(middle_m, 0.003) << view.image;
    worst_middle_m = std::max(worst_middle_m, middle_m);
  }
  const camera::Intrinsics& k = result.intrinsics;
  const camera::Intrinsics& t = truth.intrinsics();
  EXPECT_NEAR(k.fx_px / t.fx_px, 1.0, 0.005);
  EXPECT_NEAR(k.fy_px / t.fy_px, 1.0, 0.005);
  EXPECT_NEAR(k.cx_px, t.cx_px, 2.0);
  EXPECT_NEAR(k.cy_px, t.cy_px, 2.0);
  EXPECT_NEAR(k.distortion[0], t.distortion[0], 0.01);
  EXPECT_NEAR(k.distortion[1], t.distortion[1], 0.03);
  EXPECT_LT(result.rms_error_px, 0.1);
  std::printf(
      "[ measured ] %zu synthetic views 1280x720 (fx = fy = 900, c = (650, 355), k1 -0.1, "
      "k2 0.02): RMS %.4f px; fx %.3f (%+.4f%%) fy %.3f (%+.4f%%) cx %.3f (%+.3f) cy %.3f "
      "(%+.3f) px; k1 %.5f k2 %.5f p1 %.2e p2 %.2e k3 %.4f; corners vs truth: worst view RMS "
      "%.4f px; board middle worst %.2f mm\n",
      result.used_views(), result.rms_error_px, k.fx_px, 100 * (k.fx_px / t.fx_px - 1), k.fy_px,
      100 * (k.fy_px / t.fy_px - 1), k.cx_px, k.cx_px - t.cx_px, k.cy_px, k.cy_px - t.cy_px,
      k.distortion[0], k.distortion[1], k.distortion[2], k.distortion[3], k.distortion[4],
      worst_corner_px, 1000 * worst_middle_m);
}

// --- Refusals ---

TEST(ListCalibrationImages, TakesImageFilesOfTheDirectoryInNameOrder) {
  const TempDir dir;
  for (const char* name :
       {"b.PNG", "a.jpg", "c.jpeg", "d.bmp", "e.tif", "f.TIFF", "notes.txt", "image.png.bak"}) {
    std::ofstream(dir / name) << "x";
  }
  fs::create_directories(dir / "sub.png");
  std::ofstream(dir / "sub.png" / "g.png") << "x";
  std::vector<std::string> names;
  for (const fs::path& p : ListCalibrationImages(dir.path())) {
    names.push_back(p.filename().string());
  }
  EXPECT_EQ(names,
            (std::vector<std::string>{"a.jpg", "b.PNG", "c.jpeg", "d.bmp", "e.tif", "f.TIFF"}));
}

TEST(ListCalibrationImages, RefusesADirectoryWithoutImagesOrNoDirectory) {
  const TempDir dir;
  std::ofstream(dir / "notes.txt") << "no images here";
  const std::string empty = ErrorMessage([&] { (void)ListCalibrationImages(dir.path()); });
  EXPECT_NE(empty.find(dir.path().string() + ": no images (.png, .jpg, .jpeg, .bmp, .tif, .tiff)"),
            std::string::npos)
      << empty;
  const std::string missing = ErrorMessage([&] { (void)ListCalibrationImages(dir / "missing"); });
  EXPECT_NE(missing.find("missing: no such directory"), std::string::npos) << missing;
  const std::string file = ErrorMessage([&] { (void)ListCalibrationImages(dir / "notes.txt"); });
  EXPECT_NE(file.find("notes.txt: not a directory"), std::string::npos) << file;
}

TEST(Calibrate, RefusesTooFewUsableViewsListingWhatWasWrongWithTheOthers) {
  const TempDir dir;
  const std::vector<fs::path> photos = SamplePhotos();
  ASSERT_GE(photos.size(), 2u);
  fs::copy_file(photos[0], dir / "a.jpg");
  fs::copy_file(photos[1], dir / "b.jpg");
  ASSERT_TRUE(
      cv::imwrite((dir / "c_blank.png").string(), cv::Mat(480, 640, CV_8U, cv::Scalar(200))));
  std::ofstream(dir / "d_broken.png") << "not a PNG";
  std::vector<fs::path> images = ListCalibrationImages(dir.path());
  images.push_back(dir / "e_missing.png");
  const std::string message = ErrorMessage([&] { (void)Calibrate(images, kSampleBoard, {}); });
  for (const std::string& expected : std::vector<std::string>{
           "the board (9x6 inner corners) was found in 2 of 5 images; calibration needs at least 3 "
           "views",
           "c_blank.png (board not found (9x6 inner corners))",
           "d_broken.png (unreadable: not an image OpenCV can decode)",
           "e_missing.png (unreadable: no such file)"}) {
    EXPECT_NE(message.find(expected), std::string::npos)
        << "missing \"" << expected << "\" in " << message;
  }
  EXPECT_EQ(message.find("a.jpg"), std::string::npos) << message;

  EXPECT_NE(ErrorMessage([] {
              (void)Calibrate({}, kSampleBoard, {});
            }).find("calibration: no images given"),
            std::string::npos);
  EXPECT_NE(ErrorMessage([&] {
              (void)Calibrate(images, BoardSpec{.cols = 9, .rows = 1, .square_m = 0.02}, {});
            }).find("ROWS (inner corners per column) must be at least 3, got 1"),
            std::string::npos);
}

TEST(Calibrate, RefusesImagesOfDifferentSizesOrLeavesThemOutWhenAsked) {
  const TempDir dir;
  const std::vector<fs::path> photos = SamplePhotos();
  ASSERT_GE(photos.size(), 4u);
  // An image without the board is not used whatever its size (like left.jpg, 612x459, beside
  // OpenCV's sample photos): it sets no size.
  ASSERT_TRUE(cv::imwrite((dir / "blank.png").string(), cv::Mat(80, 100, CV_8U, cv::Scalar(128))));
  std::vector<fs::path> images = {dir / "blank.png"};
  for (std::size_t i = 0; i < 3; ++i) images.push_back(photos[i]);
  cv::Mat small;
  cv::resize(cv::imread(photos[3].string()), small, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
  ASSERT_TRUE(cv::imwrite((dir / "small.png").string(), small));
  images.insert(images.begin() + 2, dir / "small.png");

  std::vector<ViewStatus> seen;
  const std::string message = ErrorMessage([&] {
    (void)Calibrate(images, kSampleBoard, {},
                    [&](const CalibrationView& view, std::size_t, std::size_t) {
                      seen.push_back(view.status);
                    });
  });
  EXPECT_NE(message.find("images differ in size: small.png is 320x240 but the first image with "
                         "the board, " +
                         photos[0].filename().string() + ", is 640x480"),
            std::string::npos)
      << message;
  // Refused at the odd image, without searching the rest for the board.
  EXPECT_EQ(seen, (std::vector<ViewStatus>{ViewStatus::kBoardNotFound, ViewStatus::kUsed,
                                           ViewStatus::kDifferentSize}));

  const CalibrationResult result =
      Calibrate(images, kSampleBoard, {.skip_images_of_other_size = true});
  EXPECT_EQ(result.used_views(), 3u);
  ASSERT_EQ(result.views.size(), 5u);
  EXPECT_EQ(result.views[0].status, ViewStatus::kBoardNotFound);
  const CalibrationView& odd = result.views[2];
  EXPECT_EQ(odd.status, ViewStatus::kDifferentSize);
  EXPECT_EQ(odd.problem, "different size: 320x240, the first image with the board (" +
                             photos[0].filename().string() + ") is 640x480");
  EXPECT_EQ(odd.width_px, 320);
  EXPECT_TRUE(odd.corners_px.empty());
  EXPECT_FALSE(odd.rms_error_px.has_value());
  EXPECT_EQ(result.intrinsics.width_px, 640);
  EXPECT_EQ(result.intrinsics.height_px, 480);
}

// --- The calibration file ---

TEST(SaveCalibration, WritesSaveOpenCvCalibrationsLayoutThenTheExtrasAndReadsBackEqual) {
  const TempDir dir;
  const CalibrationResult& result = SampleCalibration();
  const CalibrationOptions options;
  const fs::path path = dir / "camera.yaml";
  SaveCalibration(path, result, kSampleBoard, options, "2026-11-27T05:10:42Z");
  EXPECT_EQ(camera::LoadOpenCvCalibration(path), result.intrinsics);

  // Byte for byte what the camera model's writer writes, then more keys.
  camera::SaveOpenCvCalibration(dir / "plain.yaml", result.intrinsics);
  const std::string plain = ReadText(dir / "plain.yaml");
  const std::string ours = ReadText(path);
  ASSERT_GT(plain.size(), 100u);
  EXPECT_EQ(ours.substr(0, plain.size()), plain) << ours;

  cv::FileStorage fs(path.string(), cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  EXPECT_EQ(static_cast<std::string>(fs["calibration_time"]), "2026-11-27T05:10:42Z");
  EXPECT_EQ(static_cast<int>(fs["nframes"]), static_cast<int>(result.used_views()));
  EXPECT_EQ(static_cast<int>(fs["board_width"]), 9);
  EXPECT_EQ(static_cast<int>(fs["board_height"]), 6);
  EXPECT_EQ(static_cast<double>(fs["square_size"]), 0.025);
  EXPECT_EQ(static_cast<int>(fs["flags"]), OpenCvCalibrationFlags(options));
  EXPECT_EQ(static_cast<double>(fs["avg_reprojection_error"]), result.rms_error_px);
  cv::Mat per_view;
  fs["per_view_reprojection_errors"] >> per_view;
  ASSERT_EQ(per_view.total(), result.used_views());
  const cv::FileNode files = fs["image_files"];
  ASSERT_TRUE(files.isSeq());
  ASSERT_EQ(files.size(), result.used_views());
  for (std::size_t i = 0; i < result.views.size(); ++i) {
    EXPECT_EQ(static_cast<std::string>(files[static_cast<int>(i)]),
              result.views[i].image.filename().string());
    EXPECT_EQ(per_view.at<double>(static_cast<int>(i)), *result.views[i].rms_error_px);
  }
  EXPECT_TRUE(fs["images_not_used"].isSeq());
  EXPECT_EQ(fs["images_not_used"].size(), 0u);

  // The other formats read back equal too; another extension is refused.
  for (const char* name : {"camera.xml", "camera.json", "camera.YML"}) {
    SaveCalibration(dir / name, result, kSampleBoard, options);
    EXPECT_EQ(camera::LoadOpenCvCalibration(dir / name), result.intrinsics) << name;
  }
  const std::string bad =
      ErrorMessage([&] { SaveCalibration(dir / "camera.txt", result, kSampleBoard, options); });
  EXPECT_NE(bad.find("camera.txt: a calibration file's name must end in .yaml, .yml, .xml or "
                     ".json (it picks the format), got \".txt\""),
            std::string::npos)
      << bad;
  EXPECT_FALSE(fs::exists(dir / "camera.txt"));
}

TEST(SaveCalibration, ListsTheImagesNotUsedWithTheirReasons) {
  const TempDir dir;
  std::vector<fs::path> images = SamplePhotos();
  ASSERT_GE(images.size(), 3u);
  images.resize(3);
  ASSERT_TRUE(cv::imwrite((dir / "blank.png").string(), cv::Mat(480, 640, CV_8U, cv::Scalar(128))));
  images.push_back(dir / "blank.png");
  const CalibrationResult result = Calibrate(images, kSampleBoard, {.distortion_coefficients = 4});
  SaveCalibration(dir / "camera.yaml", result, kSampleBoard, {.distortion_coefficients = 4});
  EXPECT_EQ(camera::LoadOpenCvCalibration(dir / "camera.yaml"), result.intrinsics);
  cv::FileStorage fs((dir / "camera.yaml").string(), cv::FileStorage::READ);
  const cv::FileNode not_used = fs["images_not_used"];
  ASSERT_EQ(not_used.size(), 1u);
  EXPECT_EQ(static_cast<std::string>(not_used[0]["file"]), "blank.png");
  EXPECT_EQ(static_cast<std::string>(not_used[0]["reason"]), "board not found (9x6 inner corners)");
  EXPECT_EQ(static_cast<int>(fs["nframes"]), 3);
  EXPECT_FALSE(fs["calibration_time"].isString());  // none given
}

TEST(UtcTimeText, IsIso8601InUtc) {
  EXPECT_EQ(UtcTimeText(std::chrono::system_clock::time_point(std::chrono::seconds(1795756242))),
            "2026-11-27T05:10:42Z");
}

// --- The program ---

TEST(CalibrateProgram, CalibratesFromADirectoryAndExitsWithStatus1OnBadInput) {
  const std::string program = testing::ProgramPath("autodrive-eye");
  ASSERT_TRUE(fs::exists(program)) << program << " is not built (ninja autodrive-eye)";
  const TempDir dir;
  fs::create_directories(dir / "photos");
  for (const fs::path& photo : SamplePhotos())
    fs::copy_file(photo, dir / "photos" / photo.filename());
  ASSERT_TRUE(cv::imwrite((dir / "photos" / "zz_blank.png").string(),
                          cv::Mat(480, 640, CV_8U, cv::Scalar(128))));
  const fs::path out = dir / "camera.yaml";
  const auto [code, text] = RunProgram({program, "calibrate", "--images", (dir / "photos").string(),
                                        "--board", "chessboard:9x6:0.025", "--out", out.string()});
  EXPECT_EQ(code, 0) << text;
  for (const std::string& expected : std::vector<std::string>{
           "calibrate: [1/14] left01.jpg: board found", "left01.jpg    found     RMS 0.",
           "zz_blank.png  not used: board not found (9x6 inner corners)", "views used: 13 of 14",
           "RMS reprojection error: 0.", "fx: 53", "distortion (k1 k2 p1 p2 k3): -0.2",
           "wrote " + out.string()}) {
    EXPECT_NE(text.find(expected), std::string::npos) << "missing \"" << expected << "\" in\n"
                                                      << text;
  }
  ASSERT_TRUE(fs::exists(out)) << text;
  const camera::Intrinsics written = camera::LoadOpenCvCalibration(out);
  EXPECT_NEAR(written.fx_px, SampleCalibration().intrinsics.fx_px, 1e-9);
  EXPECT_NEAR(written.cx_px, SampleCalibration().intrinsics.cx_px, 1e-9);

  const auto [bad_board_code, bad_board] =
      RunProgram({program, "calibrate", "--images", (dir / "photos").string(), "--board",
                  "chessboard:9x6", "--out", (dir / "b.yaml").string()});
  EXPECT_EQ(bad_board_code, 1) << bad_board;
  EXPECT_NE(bad_board.find("autodrive-eye calibrate: bad board \"chessboard:9x6\""),
            std::string::npos)
      << bad_board;
  const auto [no_images_code, no_images] =
      RunProgram({program, "calibrate", "--images", dir.path().string(), "--board",
                  "chessboard:9x6:0.025", "--out", (dir / "c.yaml").string()});
  EXPECT_EQ(no_images_code, 1) << no_images;
  EXPECT_NE(no_images.find("autodrive-eye calibrate: " + dir.path().string() + ": no images"),
            std::string::npos)
      << no_images;
  EXPECT_FALSE(fs::exists(dir / "b.yaml"));
  EXPECT_FALSE(fs::exists(dir / "c.yaml"));

  const auto [help_code, help] = RunProgram({program, "calibrate", "--help"});
  EXPECT_EQ(help_code, 0) << help;
  for (const std::string& expected :
       std::vector<std::string>{"--images", "--board", "chessboard:COLSxROWS:SQUARE_M", "--out",
                                "--model", "Example:"}) {
    EXPECT_NE(help.find(expected), std::string::npos) << expected << " not in\n" << help;
  }
}

}  // namespace
}  // namespace autodrive::eye
