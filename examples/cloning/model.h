#pragma once
/// @file
/// The behavioural-cloning case study's network and what it sees (README.md beside this file):
/// the paper's 6-layer CNN (four convolutions, two fully connected layers) from the front
/// camera's frame to the car's throttle and steering, in libtorch (CPU).
///
/// A frame of any size is first resized to 160 x 90 (the data set's size), the sky above row 30
/// cut off, and the rest scaled to [-1, 1] per channel: a 3 x 60 x 160 tensor. The recorder,
/// the trainer and the driving agent use these functions alone, so that the network sees in the
/// car what it was trained on.

#include <torch/torch.h>

#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

namespace autodrive::examples::cloning {

inline constexpr int kFrameWidth = 160;  ///< the data set's frames, pixels
inline constexpr int kFrameHeight = 90;
inline constexpr int kCropTop = 30;  ///< rows above this (the sky, the far walls) dropped
inline constexpr int kInputHeight = kFrameHeight - kCropTop;

/// Four convolutions (24, 36, 48 and 64 channels; 5 x 5 stride 2 thrice, then 3 x 3) with ELU,
/// then 64 units and the two outputs: throttle and steering, in the devkit's normalised units.
class CloningNetImpl : public torch::nn::Module {
 public:
  CloningNetImpl();
  /// `x`: N x 3 x 60 x 160 (`Preprocess`); returns N x 2 (throttle, steering).
  torch::Tensor forward(torch::Tensor x);

 private:
  torch::nn::Conv2d conv1_{nullptr}, conv2_{nullptr}, conv3_{nullptr}, conv4_{nullptr};
  torch::nn::Linear fc1_{nullptr}, fc2_{nullptr};
  torch::nn::Dropout dropout_{nullptr};
};
TORCH_MODULE(CloningNet);

/// The network's input from an 8-bit RGB frame (rows top first): 3 x 60 x 160, float.
[[nodiscard]] torch::Tensor Preprocess(const cv::Mat& rgb);

/// Writes the model's weights to `path` / reads them back into `net`.
/// @throws InputError naming the file when it cannot be written or is not such a model.
void SaveModel(CloningNet& net, const std::string& path);
void LoadModel(CloningNet& net, const std::string& path);

}  // namespace autodrive::examples::cloning
