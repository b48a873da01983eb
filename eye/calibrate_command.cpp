// autodrive-eye calibrate: a camera's intrinsics and distortion from photos of a chessboard.
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "eye/calibration.h"
#include "eye/commands.h"

namespace autodrive::eye::cli {

namespace {

struct CalibrateArgs {
  std::string images;
  std::string board;
  std::string out;
  int model = 5;
  bool fix_principal_point = false;
  bool fix_aspect_ratio = false;
  bool skip_other_sizes = false;
  bool quiet = false;
};

std::string Name(const std::filesystem::path& path) { return path.filename().string(); }

// The distortion coefficients' names for a model of `n` of them.
const char* DistortionNames(std::size_t n) {
  switch (n) {
    case 4:
      return "k1 k2 p1 p2";
    case 5:
      return "k1 k2 p1 p2 k3";
    default:
      return "k1 k2 p1 p2 k3 k4 k5 k6";
  }
}

void Calibrate(const CalibrateArgs& args) {
  const BoardSpec board = ParseBoardSpec(args.board);
  CalibrationOptions options;
  options.distortion_coefficients = args.model;
  options.fix_principal_point = args.fix_principal_point;
  options.fix_aspect_ratio = args.fix_aspect_ratio;
  options.skip_images_of_other_size = args.skip_other_sizes;
  options.Validate();
  // The output is checked before the (long) search for the board, not after it.
  const std::filesystem::path out = args.out;
  CheckCalibrationFileName(out);
  const std::filesystem::path out_dir =
      out.parent_path().empty() ? std::filesystem::path(".") : out.parent_path();
  std::error_code ec;
  AUTODRIVE_THROW_UNLESS(
      std::filesystem::is_directory(out_dir, ec),
      "--out " << args.out << ": no directory " << out_dir.string() << " to write it in");
  const std::vector<std::filesystem::path> images = ListCalibrationImages(args.images);

  bool refused_size = false;
  const CalibrationProgress progress = [&](const CalibrationView& view, std::size_t index,
                                           std::size_t count) {
    refused_size = view.status == ViewStatus::kDifferentSize && !args.skip_other_sizes;
    if (args.quiet) return;
    std::fprintf(stderr, "calibrate: [%zu/%zu] %s: %s\n", index + 1, count,
                 Name(view.image).c_str(),
                 view.status == ViewStatus::kUsed ? "board found" : view.problem.c_str());
  };
  if (!args.quiet) {
    std::fprintf(stderr, "calibrate: %zu images in %s, board %s\n", images.size(),
                 args.images.c_str(), BoardSpecText(board).c_str());
  }
  CalibrationResult result;
  try {
    result = eye::Calibrate(images, board, options, progress);
  } catch (const InputError& e) {
    if (!refused_size) throw;
    throw InputError(std::string(e.what()) + " (--skip-other-sizes leaves them out)");
  }
  SaveCalibration(out, result, board, options, UtcTimeText(std::chrono::system_clock::now()));

  std::size_t width = 0;
  for (const CalibrationView& view : result.views) width = std::max(width, Name(view.image).size());
  for (const CalibrationView& view : result.views) {
    if (view.status == ViewStatus::kUsed) {
      std::printf("%-*s  found     RMS %.3f px\n", static_cast<int>(width),
                  Name(view.image).c_str(), view.rms_error_px.value_or(0.0));
    } else {
      std::printf("%-*s  not used: %s\n", static_cast<int>(width), Name(view.image).c_str(),
                  view.problem.c_str());
    }
  }
  const camera::Intrinsics& k = result.intrinsics;
  const IntrinsicsStdDev& sd = result.std_dev;
  std::printf("views used: %zu of %zu\n", result.used_views(), result.views.size());
  std::printf("RMS reprojection error: %.4f px\n", result.rms_error_px);
  std::printf("image: %dx%d px\n", k.width_px, k.height_px);
  std::printf("fx: %.3f px (std dev %.3f)\n", k.fx_px, sd.fx_px);
  std::printf("fy: %.3f px (std dev %.3f)\n", k.fy_px, sd.fy_px);
  std::printf("cx: %.3f px (std dev %.3f)\n", k.cx_px, sd.cx_px);
  std::printf("cy: %.3f px (std dev %.3f)\n", k.cy_px, sd.cy_px);
  std::printf("distortion (%s):", DistortionNames(k.distortion.size()));
  for (const double c : k.distortion) std::printf(" %.6g", c);
  std::printf("\n");
  std::printf("wrote %s\n", out.string().c_str());
}

}  // namespace

void AddCalibrate(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "calibrate",
      "calibrate a camera from photos of a chessboard: finds the board's inner corners in every "
      "image of --images, fits the intrinsics (fx, fy, cx, cy) and lens distortion with "
      "OpenCV, prints each image's RMS reprojection error (or why it was not used) and the "
      "overall one, and writes --out in OpenCV's calibration layout (image_width, "
      "image_height, camera_matrix, distortion_coefficients), which a camera's `calibration` "
      "key reads (the Eye's cameras, the simulator's lenses). Take 10 to 20 photos at the camera's "
      "working "
      "resolution, the board tilted in each and covering every part of the image between them");
  cmd->footer(
      "Example: autodrive-eye calibrate --images photos/ --board chessboard:9x6:0.025 "
      "--out camera.yaml");
  auto args = std::make_shared<CalibrateArgs>();
  cmd->add_option("--images", args->images,
                  "directory of photos of the board: every .png, .jpg, .jpeg, .bmp, .tif and "
                  ".tiff file in it, in name order")
      ->required();
  cmd->add_option("--board", args->board,
                  "the board, chessboard:COLSxROWS:SQUARE_M: inner corners (where four squares "
                  "meet) per row and per column, and the side of a square in metres; "
                  "e.g. chessboard:9x6:0.025 for 10 x 7 squares of 25 mm")
      ->required();
  cmd->add_option("--out", args->out,
                  "calibration file to write; .yaml, .yml, .xml or .json picks the format")
      ->required();
  cmd->add_option("--model", args->model,
                  "distortion coefficients: 5 (k1 k2 p1 p2 k3, most lenses), 8 (OpenCV's "
                  "rational model, wide-angle lenses) or 4 (k1 k2 p1 p2, long lenses)")
      ->check(CLI::IsMember({5, 8, 4}))
      ->capture_default_str();
  cmd->add_flag("--fix-principal-point", args->fix_principal_point,
                "keep the principal point at the image centre instead of fitting it");
  cmd->add_flag("--fix-aspect-ratio", args->fix_aspect_ratio, "fit one focal length, fx = fy");
  cmd->add_flag(
      "--skip-other-sizes", args->skip_other_sizes,
      "leave out images with the board whose size differs from that of the first image with "
      "it (default: refuse them all)");
  cmd->add_flag("-q,--quiet", args->quiet, "no progress on stderr");
  cmd->callback([args] {
    try {
      Calibrate(*args);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "autodrive-eye calibrate: %s\n", e.what());
      throw CLI::RuntimeError(1);
    }
  });
}

}  // namespace autodrive::eye::cli
