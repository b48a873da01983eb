// The behavioural-cloning example's pieces: the data set reader's refusals, balancing, the
// network's input, and training that learns (a steering that the frames show, learnt from
// them), and the model written and read back.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/test_support.h"
#include "examples/cloning/dataset.h"
#include "examples/cloning/model.h"
#include "examples/cloning/train.h"

namespace autodrive::examples::cloning {
namespace {

// A frame whose road bends: a bright band across the lower part whose horizontal place says
// the steering (band left of the middle: steer left, positive), over a noisy grey background.
cv::Mat BendFrame(double steering, std::mt19937_64& rng) {
  cv::Mat bgr(kFrameHeight, kFrameWidth, CV_8UC3, cv::Scalar(90, 90, 90));
  cv::RNG draw(rng());
  cv::Mat noise(bgr.size(), CV_8UC3);
  draw.fill(noise, cv::RNG::UNIFORM, 0, 40);
  bgr += noise;
  const int centre = static_cast<int>(kFrameWidth / 2 - steering * 60);
  cv::rectangle(bgr, cv::Point(centre - 12, kCropTop + 5), cv::Point(centre + 12, kFrameHeight),
                cv::Scalar(230, 230, 230), cv::FILLED);
  return bgr;
}

// A data set folder as `autodrive-sim record` writes it, of `n` frames with steering uniform
// in [-0.8, 0.8] and throttle 0.6.
void WriteDataset(const std::filesystem::path& folder, int n, std::uint64_t seed) {
  std::filesystem::create_directories(folder);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> s(-0.8, 0.8);
  std::ofstream labels(folder / "labels.csv");
  labels << "frame,stamp_s,throttle,steering,speed_mps,yaw_rate_radps,x_m,y_m,yaw_rad\n";
  for (int i = 0; i < n; ++i) {
    const double steering = s(rng);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.png", i);
    ASSERT_TRUE(cv::imwrite((folder / name).string(), BendFrame(steering, rng)));
    labels << i << ',' << i / 15.0 << ",0.6," << steering << ",0.15,0,1,2,0\n";
  }
}

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

TEST(CloningDatasetTest, ABadRowIsRefusedWithItsFileAndLine) {
  const test::TempDir dir("cloning");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv: cannot read it"),
            std::string::npos);
  WriteDataset(dir.path(), 3, 1);
  EXPECT_EQ(ReadDrivingDataset(dir.path()).size(), 3u);
  const std::string header =
      "frame,stamp_s,throttle,steering,speed_mps,yaw_rate_radps,x_m,y_m,yaw_rad\n";
  WriteFile(dir.path() / "labels.csv",
            header + "0,0,0.6,0.1,0,0,0,0,0\n1,0.1,0.6,left,0,0,0,0,0\n");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv:3: steering \"left\" is not a number"),
            std::string::npos);
  WriteFile(dir.path() / "labels.csv", header + "0,0,0.6,1.5,0,0,0,0,0\n");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv:2: throttle and steering are normalised"),
            std::string::npos);
  WriteFile(dir.path() / "labels.csv", header + "7,0,0.6,0.1,0,0,0,0,0\n");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv:2: no frame frame_000007.png"),
            std::string::npos);
  WriteFile(dir.path() / "labels.csv", header + "0,0,0.6\n");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv:2: 3 columns, the header has 9"),
            std::string::npos);
  WriteFile(dir.path() / "labels.csv", "frame,stamp_s,throttle\n");
  EXPECT_NE(test::ErrorMessage([&] {
              (void)ReadDrivingDataset(dir.path());
            }).find("labels.csv:1: no column \"steering\""),
            std::string::npos);
}

TEST(CloningDatasetTest, BalancingThinsTheStraightRoadAndKeepsEveryCurve) {
  std::vector<LabelledFrame> frames;
  for (int i = 0; i < 900; ++i) frames.push_back({"f", 0.6f, 0.0f});  // straight
  for (int i = 0; i < 50; ++i) frames.push_back({"f", 0.6f, 0.5f});   // left curve
  for (int i = 0; i < 50; ++i) frames.push_back({"f", 0.6f, -0.5f});  // right curve
  const std::vector<LabelledFrame> out = Balance(frames, 21, 1.5, 7);
  int straight = 0, left = 0, right = 0;
  for (const LabelledFrame& f : out) {
    straight += f.steering == 0.0f;
    left += f.steering > 0.0f;
    right += f.steering < 0.0f;
  }
  EXPECT_EQ(straight, 500);  // 1.5 x 1000 / 3 bins
  EXPECT_EQ(left, 50);
  EXPECT_EQ(right, 50);
}

TEST(CloningModelTest, TheInputIsTheCroppedFrameScaledToPlusMinusOneAtAnySize) {
  std::mt19937_64 rng(3);
  cv::Mat rgb;
  cv::cvtColor(BendFrame(0.3, rng), rgb, cv::COLOR_BGR2RGB);
  const torch::Tensor x = Preprocess(rgb);
  EXPECT_EQ(x.sizes(), (std::vector<long>{3, kInputHeight, kFrameWidth}));
  EXPECT_GE(x.min().item<double>(), -1.0);
  EXPECT_LE(x.max().item<double>(), 1.0);
  cv::Mat big;
  cv::resize(rgb, big, cv::Size(2 * kFrameWidth, 2 * kFrameHeight), 0, 0, cv::INTER_NEAREST);
  EXPECT_LT((Preprocess(big) - x).abs().max().item<double>(), 1e-6);
}

TEST(CloningTrainTest, TheNetworkLearnsTheSteeringTheFramesShowAndIsWrittenAndReadBack) {
  const test::TempDir dir("cloning");
  WriteDataset(dir.path() / "a", 240, 11);
  WriteDataset(dir.path() / "b", 240, 12);
  torch::set_num_threads(1);
  torch::manual_seed(1);
  CloningNet net;
  TrainOptions options;
  options.epochs = 6;
  const TrainReport r = Train(net, {dir.path() / "a", dir.path() / "b"}, options);
  EXPECT_EQ(r.frames_read, 480u);
  ASSERT_EQ(r.epochs.size(), 6u);
  // Labels uniform in [-0.8, 0.8] and 0.6: guessing their means would cost about 0.107 on the
  // steering, 0.053 on the mean of the two outputs.
  EXPECT_LT(r.epochs.back().validation_loss, 0.02) << "it did not learn";

  // New frames, never seen: the steering's sign and size follow the band.
  std::mt19937_64 rng(99);
  const auto predict = [&](CloningNet& n, double steering) {
    cv::Mat rgb;
    cv::cvtColor(BendFrame(steering, rng), rgb, cv::COLOR_BGR2RGB);
    const torch::NoGradGuard no_grad;
    return n->forward(Preprocess(rgb).unsqueeze(0))[0][1].item<double>();
  };
  EXPECT_GT(predict(net, 0.6), 0.3);
  EXPECT_LT(predict(net, -0.6), -0.3);

  const std::string path = (dir.path() / "model.pt").string();
  SaveModel(net, path);
  CloningNet back;
  LoadModel(back, path);
  back->eval();
  cv::Mat rgb;
  cv::cvtColor(BendFrame(0.2, rng), rgb, cv::COLOR_BGR2RGB);
  const torch::NoGradGuard no_grad;
  const torch::Tensor x = Preprocess(rgb).unsqueeze(0);
  EXPECT_TRUE(torch::equal(net->forward(x), back->forward(x)));

  WriteFile(dir.path() / "junk.pt", "not a model");
  EXPECT_NE(test::ErrorMessage([&] {
              LoadModel(back, (dir.path() / "junk.pt").string());
            }).find("junk.pt: not a model of this network"),
            std::string::npos);
}

}  // namespace
}  // namespace autodrive::examples::cloning
