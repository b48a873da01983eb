#include "examples/cloning/model.h"

#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace autodrive::examples::cloning {

namespace {
torch::nn::Conv2dOptions Conv(int in, int out, int kernel, int stride) {
  return torch::nn::Conv2dOptions(in, out, kernel).stride(stride);
}
// The size of the last convolution's output for the 60 x 160 input.
constexpr int Out(int in, int kernel, int stride) { return (in - kernel) / stride + 1; }
constexpr int kH = Out(Out(Out(Out(kInputHeight, 5, 2), 5, 2), 5, 2), 3, 1);
constexpr int kW = Out(Out(Out(Out(kFrameWidth, 5, 2), 5, 2), 5, 2), 3, 1);
}  // namespace

CloningNetImpl::CloningNetImpl()
    : conv1_(register_module("conv1", torch::nn::Conv2d(Conv(3, 24, 5, 2)))),
      conv2_(register_module("conv2", torch::nn::Conv2d(Conv(24, 36, 5, 2)))),
      conv3_(register_module("conv3", torch::nn::Conv2d(Conv(36, 48, 5, 2)))),
      conv4_(register_module("conv4", torch::nn::Conv2d(Conv(48, 64, 3, 1)))),
      fc1_(register_module("fc1", torch::nn::Linear(64 * kH * kW, 64))),
      fc2_(register_module("fc2", torch::nn::Linear(64, 2))),
      dropout_(register_module("dropout", torch::nn::Dropout(0.3))) {}

torch::Tensor CloningNetImpl::forward(torch::Tensor x) {
  x = torch::elu(conv1_->forward(x));
  x = torch::elu(conv2_->forward(x));
  x = torch::elu(conv3_->forward(x));
  x = torch::elu(conv4_->forward(x));
  x = dropout_->forward(x.flatten(1));
  x = torch::elu(fc1_->forward(x));
  return fc2_->forward(x);
}

torch::Tensor Preprocess(const cv::Mat& rgb) {
  AUTODRIVE_CHECK(rgb.type() == CV_8UC3, "an 8-bit RGB frame expected");
  cv::Mat sized = rgb;
  if (rgb.cols != kFrameWidth || rgb.rows != kFrameHeight) {
    cv::resize(rgb, sized, cv::Size(kFrameWidth, kFrameHeight), 0, 0, cv::INTER_AREA);
  }
  const cv::Mat crop = sized.rowRange(kCropTop, kFrameHeight).clone();  // contiguous
  const torch::Tensor t =
      torch::from_blob(crop.data, {kInputHeight, kFrameWidth, 3}, torch::kUInt8);
  return t.permute({2, 0, 1}).to(torch::kFloat32).div(127.5).sub(1.0).contiguous();
}

void SaveModel(CloningNet& net, const std::string& path) {
  try {
    torch::save(net, path);
  } catch (const c10::Error& e) {
    throw InputError(path + ": cannot write the model: " + e.what_without_backtrace());
  }
}

void LoadModel(CloningNet& net, const std::string& path) {
  try {
    torch::load(net, path);
  } catch (const c10::Error& e) {
    throw InputError(path + ": not a model of this network (autodrive-example-cloning-train " +
                     "writes them): " + e.what_without_backtrace());
  }
}

}  // namespace autodrive::examples::cloning
