#pragma once
/// @file
/// Camera calibration from photos of a chessboard: the intrinsics and lens distortion of one
/// camera (common/camera/camera_model.h) with OpenCV's `calibrateCamera`, the reprojection
/// error overall and per photo, and the photos that could not be used and why. What
/// `autodrive-eye calibrate` runs (eye/calibrate_command.cpp, docs/eye.md).
///
/// The board: a chessboard of (COLS + 1) x (ROWS + 1) squares has COLS x ROWS inner corners,
/// where four squares meet; OpenCV finds those. Its frame B has its origin at the first inner
/// corner OpenCV reports, x along a row of COLS corners, y along a column of ROWS corners,
/// z = x cross y, and the inner corner (i, j) (column i, row j) at (i, j, 0) * square_m.
/// Pixels follow OpenCV's convention (the centre of the top-left pixel is (0, 0)), like the
/// camera model's.

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/camera/camera_model.h"

namespace autodrive::eye {

/// A chessboard calibration target. A plain value; `Validate` checks it.
struct BoardSpec {
  int cols = 0;           ///< Inner corners per row (OpenCV's patternSize.width); >= 3.
  int rows = 0;           ///< Inner corners per column (patternSize.height); >= 3.
  double square_m = 0.0;  ///< Side of one square, metres; in (0, kMaxSquareM].

  /// Throws `InputError` naming the field, the value seen and the allowed range.
  void Validate() const;

  /// Field-by-field equality (exact).
  bool operator==(const BoardSpec&) const = default;
};

/// The largest square side `BoardSpec` accepts, metres: larger is almost surely a size in
/// millimetres or centimetres (a board of 25 mm squares is `square_m` 0.025).
inline constexpr double kMaxSquareM = 1.0;

/// Reads a board from text `chessboard:COLSxROWS:SQUARE_M`, e.g. `chessboard:9x6:0.025`: 9 x 6
/// inner corners (10 x 7 squares) of 25 mm. COLS and ROWS are integers >= 3, SQUARE_M a
/// number of metres in (0, kMaxSquareM].
/// @throws InputError whose message quotes the text, names the part that is wrong and gives
/// the expected form.
[[nodiscard]] BoardSpec ParseBoardSpec(std::string_view text);

/// The text `ParseBoardSpec` reads back to `board`: `chessboard:9x6:0.025`.
[[nodiscard]] std::string BoardSpecText(const BoardSpec& board);

/// How to calibrate. A plain value with defaults; `Validate` checks it.
struct CalibrationOptions {
  /// How many distortion coefficients to fit, in OpenCV's order k1, k2, p1, p2, k3, k4, k5,
  /// k6: 4 (k3 = 0, for a long lens), 5 (the default, most lenses), or 8 (OpenCV's rational
  /// model, for wide-angle lenses; needs many varied views).
  int distortion_coefficients = 5;
  /// Keep the principal point at the image centre ((width - 1) / 2, (height - 1) / 2) instead
  /// of fitting it (OpenCV's CALIB_FIX_PRINCIPAL_POINT); for few or poorly varied views.
  bool fix_principal_point = false;
  /// Fit one focal length, fx = fy (square pixels; CALIB_FIX_ASPECT_RATIO).
  bool fix_aspect_ratio = false;
  /// Fix the tangential coefficients p1 = p2 = 0 (CALIB_ZERO_TANGENT_DIST).
  bool zero_tangential_distortion = false;
  /// What to do with an image that shows the board but whose size differs from that of the
  /// first image that showed it: false (the default) refuses the whole set (`Calibrate`
  /// throws: one camera at one resolution at a time); true leaves it out
  /// (`ViewStatus::kDifferentSize`) and goes on with the others. Images without the board are
  /// not used whatever their size.
  bool skip_images_of_other_size = false;

  /// Throws `InputError` when `distortion_coefficients` is not 4, 5 or 8.
  void Validate() const;

  /// Field-by-field equality.
  bool operator==(const CalibrationOptions&) const = default;
};

/// The fewest views (photos in which the board was found) `Calibrate` accepts.
inline constexpr std::size_t kMinCalibrationViews = 3;

/// What became of one photo.
enum class ViewStatus {
  kUsed,           ///< The board was found; the view took part in the calibration.
  kUnreadable,     ///< The file could not be read or decoded as an image.
  kBoardNotFound,  ///< The image was read but the whole board was not found in it.
  /// The board was found, but the image's size differs from that of the first image in which
  /// it was found (`CalibrationOptions::skip_images_of_other_size`).
  kDifferentSize,
};

/// A short name of `status`: "used", "unreadable", "board not found", "different size".
[[nodiscard]] std::string_view ToString(ViewStatus status);

/// One photo given to `Calibrate` and what became of it.
struct CalibrationView {
  std::filesystem::path image;  ///< The file, as given.
  ViewStatus status = ViewStatus::kUnreadable;
  /// Why the view was not used, for people ("board not found (9x6 inner corners)"); empty
  /// when it was used.
  std::string problem;
  int width_px = 0;   ///< The image's width, pixels; 0 when unreadable.
  int height_px = 0;  ///< The image's height, pixels; 0 when unreadable.
  /// The inner corners found, pixels, row by row (corner (i, j) of the board frame at index
  /// j * cols + i), refined to sub-pixel; empty when the view is not used.
  std::vector<Eigen::Vector2d> corners_px;
  /// The view's RMS reprojection error, pixels: sqrt(mean over its corners of the squared
  /// distance between the corner found and the board's corner projected with the calibrated
  /// intrinsics and the view's pose). Set for used views once `Calibrate` has finished.
  std::optional<double> rms_error_px;
  /// The pose of the board frame B (see the file comment) in the camera's optical frame C;
  /// set for used views once `Calibrate` has finished.
  std::optional<Eigen::Isometry3d> X_CB;
};

/// One standard deviation of each calibrated value, from the covariance of OpenCV's final
/// Levenberg-Marquardt step scaled by the residual (OpenCV's stdDeviationsIntrinsics). Only
/// meaningful when the residual is noise, i.e. the model fits; fixed values have 0.
struct IntrinsicsStdDev {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  std::vector<double> distortion;  ///< Same order and size as `Intrinsics::distortion`.
};

/// What `Calibrate` found.
struct CalibrationResult {
  /// The calibrated camera: the images' size, focal lengths, principal point and
  /// `CalibrationOptions::distortion_coefficients` coefficients.
  camera::Intrinsics intrinsics;
  IntrinsicsStdDev std_dev;  ///< The uncertainty of `intrinsics`.
  /// The RMS reprojection error over every corner of every used view, pixels (what
  /// `cv::calibrateCamera` returns).
  double rms_error_px = 0.0;
  /// Every photo given, in the order given.
  std::vector<CalibrationView> views;

  /// How many views were used.
  [[nodiscard]] std::size_t used_views() const;
};

/// Called by `Calibrate` after each photo has been searched for the board (before the
/// calibration, so `rms_error_px` is not set yet): the view, its index in the list and the
/// number of photos.
using CalibrationProgress =
    std::function<void(const CalibrationView& view, std::size_t index, std::size_t count)>;

/// Calibrates a camera from photos of `board`.
///
/// Each image is read as grey. The board is searched with OpenCV's classic detector
/// (`findChessboardCorners`), whose corners are refined with `cornerSubPix` in a window scaled
/// to the view's smallest corner spacing, and, where that finds none, with the sector-based
/// one (`findChessboardCornersSB`), which finds boards in blurred images and gives its own
/// sub-pixel corners (calibration.cpp says why, with measurements). The views where the board
/// was found go to `cv::calibrateCamera` with the options' flags.
///
/// @throws InputError when `images` is empty, `board` or `options` is not valid, an image
/// with the board differs in size from the first with it and
/// `options.skip_images_of_other_size` is false (thrown at that image, after `progress` has
/// been told; the message names both images and their sizes), fewer than `kMinCalibrationViews`
/// views remain (the message lists the photos not used and why), or OpenCV's calibration fails or
/// gives a camera that is not valid.
[[nodiscard]] CalibrationResult Calibrate(const std::vector<std::filesystem::path>& images,
                                          const BoardSpec& board, const CalibrationOptions& options,
                                          const CalibrationProgress& progress = {});

/// The image files in `dir` that `autodrive-eye calibrate --images DIR` takes: regular files
/// (or links to them) whose extension is .png, .jpg, .jpeg, .bmp, .tif or .tiff in any case,
/// not in subdirectories, sorted by file name.
/// @throws InputError when `dir` is not a directory or holds no such file.
[[nodiscard]] std::vector<std::filesystem::path> ListCalibrationImages(
    const std::filesystem::path& dir);

/// Writes `result` as a camera calibration file: first exactly what
/// `camera::SaveOpenCvCalibration` writes (image_width, image_height, camera_matrix,
/// distortion_coefficients as an Nx1 matrix; `camera::LoadOpenCvCalibration` and the
/// simulator's renderer read it), then, in the keys OpenCV's calibration sample uses,
/// calibration_time (when `calibration_time` is not empty), nframes, board_width,
/// board_height, square_size, flags (OpenCV's calibration flags), avg_reprojection_error,
/// per_view_reprojection_errors (an Nx1 matrix, one row per used view); and ours: image_files
/// (the used views' file names, in the order of per_view_reprojection_errors) and
/// images_not_used (a sequence of {file, reason}). The format follows the extension (.yaml,
/// .yml, .xml or .json). Overwrites an existing file.
/// @throws InputError if `CheckCalibrationFileName` does, `result.intrinsics` is not valid, or
/// the file cannot be written.
void SaveCalibration(const std::filesystem::path& path, const CalibrationResult& result,
                     const BoardSpec& board, const CalibrationOptions& options,
                     std::string_view calibration_time = {});

/// Throws `InputError` unless `path` ends in .yaml, .yml, .xml or .json (in any case): the
/// extensions `SaveCalibration` takes. For a program to check before it calibrates.
void CheckCalibrationFileName(const std::filesystem::path& path);

/// `time` as UTC text in ISO 8601, `2026-11-27T05:10:42Z`, for `SaveCalibration`.
[[nodiscard]] std::string UtcTimeText(std::chrono::system_clock::time_point time);

/// OpenCV's `calibrateCamera` flags for `options` (CALIB_FIX_K3, CALIB_RATIONAL_MODEL, ...).
[[nodiscard]] int OpenCvCalibrationFlags(const CalibrationOptions& options);

}  // namespace autodrive::eye
