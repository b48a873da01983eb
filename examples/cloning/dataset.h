#pragma once
/// @file
/// Driving data sets for behavioural cloning, as `autodrive-sim record` writes them
/// (docs/vehicle_sim.md, "Driving data sets"): a folder of `frame_NNNNNN.png` with `labels.csv`
/// (`frame,stamp_s,throttle,steering,...`). Read, balanced and augmented for training.

#include <cstdint>
#include <filesystem>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

namespace autodrive::examples::cloning {

struct LabelledFrame {
  std::filesystem::path image;  ///< the frame's PNG or JPEG
  float throttle = 0.0f;        ///< the driver's command, normalised
  float steering = 0.0f;        ///< normalised, positive left
};

/// The labelled frames of one recorded folder, in order.
/// @throws InputError naming the file and line of a bad row (a column missing, a number that is
/// not one, a label outside [-1, 1]), a frame file that is not there, or a folder without
/// labels.csv.
[[nodiscard]] std::vector<LabelledFrame> ReadDrivingDataset(const std::filesystem::path& folder);

/// At most `cap` frames in each of `bins` steering bins over [-1, 1], with cap = `factor` x the
/// mean count of the bins that have frames: the straight road's many frames thinned at random
/// (seeded), every curve's kept. Order of the rest kept.
[[nodiscard]] std::vector<LabelledFrame> Balance(const std::vector<LabelledFrame>& frames, int bins,
                                                 double factor, std::uint64_t seed);

/// A training copy of an RGB frame: brightness scaled by a factor uniform in [0.6, 1.4], each
/// channel by one more in [0.9, 1.1] (the lab's light and the camera's white balance), and
/// Gaussian noise of 3 levels.
[[nodiscard]] cv::Mat Augment(const cv::Mat& rgb, std::mt19937_64& rng);

/// Reads a frame as 8-bit RGB. @throws InputError when it cannot be read.
[[nodiscard]] cv::Mat ReadRgb(const std::filesystem::path& path);

}  // namespace autodrive::examples::cloning
