#include "eye/calibration.h"

#include <time.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <ctime>
#include <limits>
#include <optional>
#include <sstream>
#include <system_error>
#include <utility>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace autodrive::eye {
namespace {

constexpr std::string_view kBoardForm =
    "chessboard:COLSxROWS:SQUARE_M (inner corners per row x per column, square side in metres), "
    "e.g. chessboard:9x6:0.025";

// Corner detection and refinement (see FindBoard): the classic detector
// (findChessboardCorners) with its corners refined by cornerSubPix in a half-window of
// kSubPixWindowFraction x the view's smallest spacing between neighbouring corners; where it
// finds no board, the sector-based one (findChessboardCornersSB, EXHAUSTIVE | ACCURACY) with
// its own sub-pixel corners. Why, measured with OpenCV 4.6 on OpenCV's sample photos
// left01..left14 (9x6 inner corners, 640x480; 13 files, there is no left10), RMS reprojection
// error of the 5-coefficient calibration:
//   classic + cornerSubPix, fixed half-window 11 px (OpenCV's calibration sample)  0.41 px
//     (left02's squares are ~20 px wide: the window takes in the next corners, 1.22 px there)
//   classic + cornerSubPix, fixed half-window 5 px                                  0.195 px
//   SB alone                                                                        0.256 px
//   classic or SB + cornerSubPix, half-window 0.3 x the smallest spacing            0.18 px
//     (0.4 x: 0.186 px; 0.45 x: 0.47 px, the neighbouring corners again)
// and on synthetic views with known corners (1280x720, k1 = -0.1, anti-aliased, blurred by
// sigma 0.8 px), RMS distance to the true corners: SB alone 0.070 px, classic or SB + the
// scaled cornerSubPix window 0.040 px. The classic detector runs first because it is also 20
// to 50 times faster on an image that shows the board (6-50 ms against 0.25-1.1 s). The SB
// detector finds boards the classic one misses: in the sample photos blurred by a Gaussian of
// sigma 3 / 4.5 px the classic one finds 6 / 2 of the 13 boards, SB all 13 (shrunk to 0.4 x
// their size: 10 and 13). Its corners are not refined: cornerSubPix needs sharp edges, which
// such images lack; on the photos blurred by 4.5 px, RMS 0.36 px as SB gives them, 0.49 px
// refined (by 3 px: 0.26 px as given, 0.19 px refined).
constexpr double kSubPixWindowFraction = 0.3;
constexpr int kMinSubPixHalfWindowPx = 2;
constexpr int kMaxSubPixHalfWindowPx = 20;
const cv::TermCriteria kSubPixCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 40, 1e-3);
// Levenberg-Marquardt in calibrateCamera: OpenCV's default is 30 iterations.
const cv::TermCriteria kCalibrationCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100,
                                            DBL_EPSILON);

// At most this many photos are listed in the "too few views" message.
constexpr std::size_t kMaxListedProblems = 10;

[[noreturn]] void BadBoard(std::string_view text, const std::string& problem) {
  throw InputError("bad board \"" + std::string(text) + "\": " + problem + "; expected " +
                   std::string(kBoardForm));
}

std::optional<int> ParseInt(std::string_view s) {
  int value = 0;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, value);
  if (s.empty() || ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

std::optional<double> ParseDouble(std::string_view s) {
  double value = 0.0;
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, value);
  if (s.empty() || ec != std::errc() || ptr != end) return std::nullopt;
  return value;
}

std::string Text(double value) {
  std::ostringstream os;
  os << value;
  return os.str();
}

// What is wrong with `board`, in the words of the text form; nullopt when it is valid.
std::optional<std::string> BoardProblem(const BoardSpec& board) {
  if (board.cols < 3) {
    return "COLS (inner corners per row) must be at least 3, got " + std::to_string(board.cols);
  }
  if (board.rows < 3) {
    return "ROWS (inner corners per column) must be at least 3, got " + std::to_string(board.rows);
  }
  if (!std::isfinite(board.square_m) || board.square_m <= 0.0 || board.square_m > kMaxSquareM) {
    return "SQUARE_M (the side of a square, metres) must be > 0 and <= " + Text(kMaxSquareM) +
           ", got " + Text(board.square_m) + " (25 mm squares are 0.025)";
  }
  return std::nullopt;
}

std::string SizeText(int width_px, int height_px) {
  return std::to_string(width_px) + "x" + std::to_string(height_px);
}

std::string Lowercase(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string FileName(const std::filesystem::path& path) { return path.filename().string(); }

// The board's inner corners in its frame B, row by row (the order OpenCV reports them in).
std::vector<cv::Point3f> BoardPoints(const BoardSpec& board) {
  std::vector<cv::Point3f> points;
  points.reserve(static_cast<std::size_t>(board.cols * board.rows));
  for (int j = 0; j < board.rows; ++j) {
    for (int i = 0; i < board.cols; ++i) {
      points.emplace_back(static_cast<float>(i * board.square_m),
                          static_cast<float>(j * board.square_m), 0.0f);
    }
  }
  return points;
}

// The smallest distance between two corners next to each other in a row or a column, px.
double SmallestCornerSpacing(const std::vector<cv::Point2f>& corners, const cv::Size& pattern) {
  double smallest = std::numeric_limits<double>::infinity();
  const auto at = [&](int i, int j) {
    return corners[static_cast<std::size_t>(j * pattern.width + i)];
  };
  for (int j = 0; j < pattern.height; ++j) {
    for (int i = 0; i < pattern.width; ++i) {
      if (i + 1 < pattern.width) smallest = std::min(smallest, cv::norm(at(i + 1, j) - at(i, j)));
      if (j + 1 < pattern.height) smallest = std::min(smallest, cv::norm(at(i, j + 1) - at(i, j)));
    }
  }
  return smallest;
}

// The board's inner corners in `grey`, to sub-pixel, row by row; nullopt when the whole board
// is not found. See the comment above kSubPixWindowFraction for the detectors and refinement.
std::optional<std::vector<cv::Point2f>> FindBoard(const cv::Mat& grey, const cv::Size& pattern) {
  std::vector<cv::Point2f> corners;
  if (cv::findChessboardCorners(
          grey, pattern, corners,
          cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK) &&
      corners.size() == static_cast<std::size_t>(pattern.area())) {
    const int half_window = std::clamp(
        static_cast<int>(kSubPixWindowFraction * SmallestCornerSpacing(corners, pattern)),
        kMinSubPixHalfWindowPx, kMaxSubPixHalfWindowPx);
    cv::cornerSubPix(grey, corners, cv::Size(half_window, half_window), cv::Size(-1, -1),
                     kSubPixCriteria);
    return corners;
  }
  corners.clear();
  if (cv::findChessboardCornersSB(
          grey, pattern, corners,
          cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY | cv::CALIB_CB_NORMALIZE_IMAGE) &&
      corners.size() == static_cast<std::size_t>(pattern.area())) {
    return corners;
  }
  return std::nullopt;
}

// The image at `path` as 8-bit grey; empty when it cannot be read or decoded.
cv::Mat ReadGrey(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return {};  // imread would log a warning
  try {
    return cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception&) {
    return {};  // A decoder that throws on a broken file: the same as one that returns nothing.
  }
}

std::string UnreadableProblem(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return "unreadable: no such file";
  if (!std::filesystem::is_regular_file(path, ec)) return "unreadable: not a regular file";
  return "unreadable: not an image OpenCV can decode";
}

std::string TooFewViewsMessage(const CalibrationResult& result, const BoardSpec& board) {
  std::ostringstream os;
  os << "the board (" << board.cols << "x" << board.rows << " inner corners) was found in "
     << result.used_views() << " of " << result.views.size() << " images; calibration needs at "
     << "least " << kMinCalibrationViews << " views";
  std::size_t listed = 0;
  std::size_t unlisted = 0;
  for (const CalibrationView& view : result.views) {
    if (view.status == ViewStatus::kUsed) continue;
    if (listed == kMaxListedProblems) {
      ++unlisted;
      continue;
    }
    os << (listed == 0 ? "; not used: " : ", ") << FileName(view.image) << " (" << view.problem
       << ")";
    ++listed;
  }
  if (unlisted > 0) os << " and " << unlisted << " more";
  return os.str();
}

std::vector<double> Column(const cv::Mat& m) {
  std::vector<double> values;
  values.reserve(m.total());
  for (std::size_t i = 0; i < m.total(); ++i) values.push_back(m.at<double>(static_cast<int>(i)));
  return values;
}

Eigen::Isometry3d PoseFromOpenCv(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) X.linear()(r, c) = R.at<double>(r, c);
    X.translation()(r) = tvec.at<double>(r);
  }
  return X;
}

// calibration.cpp's OpenCV exception text, like camera_model.cpp's.
std::string OpenCvText(const cv::Exception& e) {
  return "OpenCV: " + e.err + (e.func.empty() ? std::string() : ": " + e.func);
}

}  // namespace

// --- Board and options ---

void BoardSpec::Validate() const {
  if (const std::optional<std::string> problem = BoardProblem(*this)) {
    throw InputError("bad board " + BoardSpecText(*this) + ": " + *problem);
  }
}

BoardSpec ParseBoardSpec(std::string_view text) {
  std::vector<std::string_view> parts;
  for (std::size_t start = 0;;) {
    const std::size_t colon = text.find(':', start);
    parts.push_back(text.substr(start, colon == std::string_view::npos ? colon : colon - start));
    if (colon == std::string_view::npos) break;
    start = colon + 1;
  }
  if (parts.size() != 3) {
    BadBoard(text, "it has " + std::to_string(parts.size()) +
                       " part(s) separated by ':', not 3 (pattern, corners, square size)");
  }
  if (parts[0] != "chessboard") {
    BadBoard(text, "unknown pattern \"" + std::string(parts[0]) +
                       "\" (the only one supported is \"chessboard\")");
  }
  const std::size_t x = parts[1].find_first_of("xX");
  const std::optional<int> cols =
      x == std::string_view::npos ? std::nullopt : ParseInt(parts[1].substr(0, x));
  const std::optional<int> rows =
      x == std::string_view::npos ? std::nullopt : ParseInt(parts[1].substr(x + 1));
  if (!cols || !rows) {
    BadBoard(text, "COLSxROWS must be two whole numbers separated by 'x', got \"" +
                       std::string(parts[1]) + "\"");
  }
  const std::optional<double> square_m = ParseDouble(parts[2]);
  if (!square_m) {
    BadBoard(text, "SQUARE_M must be a number of metres, got \"" + std::string(parts[2]) + "\"");
  }
  const BoardSpec board{.cols = *cols, .rows = *rows, .square_m = *square_m};
  if (const std::optional<std::string> problem = BoardProblem(board)) BadBoard(text, *problem);
  return board;
}

std::string BoardSpecText(const BoardSpec& board) {
  // The shortest text that reads back to the same double: 0.025, not 0.025000000000000001.
  std::array<char, 32> square{};
  const auto [end, ec] =
      std::to_chars(square.data(), square.data() + square.size(), board.square_m);
  AUTODRIVE_CHECK(ec == std::errc());
  return "chessboard:" + std::to_string(board.cols) + "x" + std::to_string(board.rows) + ":" +
         std::string(square.data(), end);
}

void CalibrationOptions::Validate() const {
  AUTODRIVE_THROW_UNLESS(
      distortion_coefficients == 4 || distortion_coefficients == 5 || distortion_coefficients == 8,
      "calibration: distortion_coefficients must be 4, 5 or 8 (OpenCV's "
      "rational model), got "
          << distortion_coefficients);
}

int OpenCvCalibrationFlags(const CalibrationOptions& options) {
  options.Validate();
  int flags = 0;
  if (options.distortion_coefficients == 4) flags |= cv::CALIB_FIX_K3;
  if (options.distortion_coefficients == 8) flags |= cv::CALIB_RATIONAL_MODEL;
  if (options.fix_principal_point) flags |= cv::CALIB_FIX_PRINCIPAL_POINT;
  if (options.fix_aspect_ratio) flags |= cv::CALIB_FIX_ASPECT_RATIO;
  if (options.zero_tangential_distortion) flags |= cv::CALIB_ZERO_TANGENT_DIST;
  return flags;
}

std::string_view ToString(ViewStatus status) {
  switch (status) {
    case ViewStatus::kUsed:
      return "used";
    case ViewStatus::kUnreadable:
      return "unreadable";
    case ViewStatus::kBoardNotFound:
      return "board not found";
    case ViewStatus::kDifferentSize:
      return "different size";
  }
  AUTODRIVE_CHECK(false, "unknown ViewStatus " << static_cast<int>(status));
  return "";
}

std::size_t CalibrationResult::used_views() const {
  return static_cast<std::size_t>(std::count_if(
      views.begin(), views.end(), [](const auto& v) { return v.status == ViewStatus::kUsed; }));
}

// --- Calibration ---

CalibrationResult Calibrate(const std::vector<std::filesystem::path>& images,
                            const BoardSpec& board, const CalibrationOptions& options,
                            const CalibrationProgress& progress) {
  board.Validate();
  options.Validate();
  AUTODRIVE_THROW_UNLESS(!images.empty(), "calibration: no images given");
  const cv::Size pattern(board.cols, board.rows);

  CalibrationResult result;
  result.views.reserve(images.size());
  // The size of the first image in which the board was found: every used view must have it
  // (an image without the board is not used, whatever its size).
  std::optional<cv::Size> image_size;
  std::filesystem::path first_image;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<std::size_t> used;  // Index in result.views of each element of image_points.
  for (std::size_t i = 0; i < images.size(); ++i) {
    CalibrationView view;
    view.image = images[i];
    const cv::Mat grey = ReadGrey(view.image);
    std::optional<std::vector<cv::Point2f>> corners;
    if (grey.empty()) {
      view.status = ViewStatus::kUnreadable;
      view.problem = UnreadableProblem(view.image);
    } else {
      view.width_px = grey.cols;
      view.height_px = grey.rows;
      std::string opencv_problem;
      try {
        corners = FindBoard(grey, pattern);
      } catch (const cv::Exception& e) {
        opencv_problem = " (" + OpenCvText(e) + ")";
      }
      if (!corners) {
        view.status = ViewStatus::kBoardNotFound;
        view.problem = "board not found (" + std::to_string(board.cols) + "x" +
                       std::to_string(board.rows) + " inner corners)" + opencv_problem;
      } else if (image_size && grey.size() != *image_size) {
        view.status = ViewStatus::kDifferentSize;
        view.problem = "different size: " + SizeText(grey.cols, grey.rows) +
                       ", the first image with the board (" + FileName(first_image) + ") is " +
                       SizeText(image_size->width, image_size->height);
        if (!options.skip_images_of_other_size) {
          if (progress) progress(view, i, images.size());
          throw InputError("images differ in size: " + FileName(view.image) + " is " +
                           SizeText(grey.cols, grey.rows) +
                           " but the first image with the board, " + FileName(first_image) +
                           ", is " + SizeText(image_size->width, image_size->height) +
                           "; calibrate one camera at one resolution at a time, or leave the "
                           "other sizes out");
        }
      } else {
        if (!image_size) {
          image_size = grey.size();
          first_image = view.image;
        }
        view.status = ViewStatus::kUsed;
        view.corners_px.reserve(corners->size());
        for (const cv::Point2f& p : *corners) view.corners_px.emplace_back(p.x, p.y);
        image_points.push_back(std::move(*corners));
        used.push_back(i);
      }
    }
    result.views.push_back(std::move(view));
    if (progress) progress(result.views.back(), i, images.size());
  }
  if (used.size() < kMinCalibrationViews) throw InputError(TooFewViewsMessage(result, board));

  const std::vector<std::vector<cv::Point3f>> object_points(used.size(), BoardPoints(board));
  // With CALIB_FIX_ASPECT_RATIO, OpenCV keeps the input's fx / fy: 1.
  cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat D;
  std::vector<cv::Mat> rvecs;
  std::vector<cv::Mat> tvecs;
  cv::Mat std_dev_intrinsics;
  cv::Mat std_dev_extrinsics;
  cv::Mat per_view_errors;
  try {
    result.rms_error_px = cv::calibrateCamera(
        object_points, image_points, *image_size, K, D, rvecs, tvecs, std_dev_intrinsics,
        std_dev_extrinsics, per_view_errors, OpenCvCalibrationFlags(options), kCalibrationCriteria);
  } catch (const cv::Exception& e) {
    throw InputError("calibration failed (" + OpenCvText(e) +
                     "); are the views varied enough (the board tilted, all over the image)?");
  }
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(result.rms_error_px) && cv::checkRange(K) && cv::checkRange(D),
      "calibration failed: OpenCV returned a camera that is not finite (RMS error "
          << result.rms_error_px
          << " px); are the views varied enough (the board tilted, all over the image)?");

  const auto n = static_cast<std::size_t>(options.distortion_coefficients);
  AUTODRIVE_CHECK(D.total() >= n && D.type() == CV_64F,
                  "OpenCV returned " << D.total() << " coefficients");
  AUTODRIVE_CHECK(std_dev_intrinsics.total() >= 4 + n && per_view_errors.total() == used.size() &&
                  rvecs.size() == used.size() && tvecs.size() == used.size());
  camera::Intrinsics& intrinsics = result.intrinsics;
  intrinsics.width_px = image_size->width;
  intrinsics.height_px = image_size->height;
  intrinsics.fx_px = K.at<double>(0, 0);
  intrinsics.fy_px = K.at<double>(1, 1);
  intrinsics.cx_px = K.at<double>(0, 2);
  intrinsics.cy_px = K.at<double>(1, 2);
  const std::vector<double> coefficients = Column(D);
  intrinsics.distortion.assign(coefficients.begin(),
                               coefficients.begin() + static_cast<std::ptrdiff_t>(n));
  try {
    intrinsics.Validate();
  } catch (const InputError& e) {
    throw InputError(std::string("calibration failed: OpenCV returned a camera that is not "
                                 "valid: ") +
                     e.what());
  }

  const std::vector<double> std_dev = Column(std_dev_intrinsics);
  result.std_dev.fx_px = std_dev[0];
  result.std_dev.fy_px = std_dev[1];
  result.std_dev.cx_px = std_dev[2];
  result.std_dev.cy_px = std_dev[3];
  result.std_dev.distortion.assign(std_dev.begin() + 4,
                                   std_dev.begin() + 4 + static_cast<std::ptrdiff_t>(n));
  for (std::size_t k = 0; k < used.size(); ++k) {
    CalibrationView& view = result.views[used[k]];
    view.rms_error_px = per_view_errors.at<double>(static_cast<int>(k));
    view.X_CB = PoseFromOpenCv(rvecs[k], tvecs[k]);
  }
  return result;
}

std::vector<std::filesystem::path> ListCalibrationImages(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw InputError(dir.string() + ": " +
                     (std::filesystem::exists(dir, ec) ? "not a directory" : "no such directory"));
  }
  static const std::array<std::string_view, 6> kExtensions = {".png", ".jpg", ".jpeg",
                                                              ".bmp", ".tif", ".tiff"};
  std::vector<std::filesystem::path> images;
  std::filesystem::directory_iterator it(dir, ec);
  for (; !ec && it != std::filesystem::directory_iterator(); it.increment(ec)) {
    const std::filesystem::path& path = it->path();
    const std::string extension = Lowercase(path.extension().string());
    std::error_code file_ec;
    if (std::find(kExtensions.begin(), kExtensions.end(), extension) != kExtensions.end() &&
        std::filesystem::is_regular_file(path, file_ec)) {
      images.push_back(path);
    }
  }
  if (ec) throw InputError(dir.string() + ": cannot list the directory (" + ec.message() + ")");
  AUTODRIVE_THROW_UNLESS(!images.empty(),
                         dir.string() << ": no images (.png, .jpg, .jpeg, .bmp, .tif, .tiff) in "
                                         "this directory");
  std::sort(images.begin(), images.end(),
            [](const auto& a, const auto& b) { return a.filename() < b.filename(); });
  return images;
}

// --- The calibration file ---

void CheckCalibrationFileName(const std::filesystem::path& path) {
  const std::string extension = Lowercase(path.extension().string());
  AUTODRIVE_THROW_UNLESS(
      extension == ".yaml" || extension == ".yml" || extension == ".xml" || extension == ".json",
      path.string() << ": a calibration file's name must end in .yaml, .yml, .xml or .json (it "
                       "picks the format), got \""
                    << path.extension().string() << "\"");
}

void SaveCalibration(const std::filesystem::path& path, const CalibrationResult& result,
                     const BoardSpec& board, const CalibrationOptions& options,
                     std::string_view calibration_time) {
  CheckCalibrationFileName(path);
  const camera::Intrinsics& intrinsics = result.intrinsics;
  std::vector<double> errors;
  for (const CalibrationView& view : result.views) {
    if (view.status == ViewStatus::kUsed)
      errors.push_back(view.rms_error_px.value_or(std::numeric_limits<double>::quiet_NaN()));
  }
  cv::Mat per_view(static_cast<int>(errors.size()), 1, CV_64F);
  for (std::size_t i = 0; i < errors.size(); ++i) {
    per_view.at<double>(static_cast<int>(i)) = errors[i];
  }
  // camera::SaveOpenCvCalibration's four keys, then the calibration's own.
  camera::SaveOpenCvCalibration(path, intrinsics, [&](cv::FileStorage& fs) {
    if (!calibration_time.empty()) fs << "calibration_time" << std::string(calibration_time);
    fs << "nframes" << static_cast<int>(errors.size());
    fs << "board_width" << board.cols;
    fs << "board_height" << board.rows;
    fs << "square_size" << board.square_m;
    fs << "flags" << OpenCvCalibrationFlags(options);
    fs << "avg_reprojection_error" << result.rms_error_px;
    fs << "per_view_reprojection_errors" << per_view;
    fs << "image_files"
       << "[";
    for (const CalibrationView& view : result.views) {
      if (view.status == ViewStatus::kUsed) fs << FileName(view.image);
    }
    fs << "]";
    fs << "images_not_used"
       << "[";
    for (const CalibrationView& view : result.views) {
      if (view.status == ViewStatus::kUsed) continue;
      fs << "{"
         << "file" << FileName(view.image) << "reason" << view.problem << "}";
    }
    fs << "]";
  });
}

std::string UtcTimeText(std::chrono::system_clock::time_point time) {
  const std::time_t t = std::chrono::system_clock::to_time_t(time);
  std::tm utc{};
  gmtime_r(&t, &utc);
  char text[32];
  const std::size_t length = std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return std::string(text, length);
}

}  // namespace autodrive::eye
