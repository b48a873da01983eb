#include "examples/cloning/train.h"

#include <algorithm>
#include <chrono>
#include <numeric>
#include <random>

#include "common/error.h"
#include "examples/cloning/dataset.h"

namespace autodrive::examples::cloning {

namespace {
double Since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The frames as recorded (augmented and preprocessed batch by batch) and their
// labels, N x 2 (throttle, steering).
struct Frames {
  std::vector<cv::Mat> rgb;
  torch::Tensor labels;
};

Frames Load(const std::vector<LabelledFrame>& frames) {
  Frames out;
  out.labels = torch::empty({static_cast<long>(frames.size()), 2});
  auto l = out.labels.accessor<float, 2>();
  for (std::size_t i = 0; i < frames.size(); ++i) {
    out.rgb.push_back(ReadRgb(frames[i].image));
    l[static_cast<long>(i)][0] = frames[i].throttle;
    l[static_cast<long>(i)][1] = frames[i].steering;
  }
  return out;
}

torch::Tensor Batch(const Frames& frames, const std::vector<std::size_t>& order, std::size_t from,
                    std::size_t to, bool augment, std::mt19937_64& rng) {
  std::vector<torch::Tensor> inputs;
  for (std::size_t k = from; k < to; ++k) {
    const cv::Mat& rgb = frames.rgb[order[k]];
    inputs.push_back(Preprocess(augment ? Augment(rgb, rng) : rgb));
  }
  return torch::stack(inputs);
}

torch::Tensor Labels(const Frames& frames, const std::vector<std::size_t>& order, std::size_t from,
                     std::size_t to) {
  std::vector<long> index;
  for (std::size_t k = from; k < to; ++k) index.push_back(static_cast<long>(order[k]));
  return frames.labels.index_select(0, torch::tensor(index, torch::kLong));
}
}  // namespace

TrainReport Train(CloningNet& net, const std::vector<std::filesystem::path>& folders,
                  const TrainOptions& options,
                  const std::function<void(int, std::size_t, std::size_t)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  AUTODRIVE_THROW_UNLESS(!folders.empty(), "no data set folder given");
  TrainReport report;
  std::vector<LabelledFrame> all;
  for (const auto& folder : folders) {
    const std::vector<LabelledFrame> f = ReadDrivingDataset(folder);
    all.insert(all.end(), f.begin(), f.end());
  }
  report.frames_read = all.size();
  const std::vector<LabelledFrame> balanced =
      Balance(all, options.balance_bins, options.balance_factor, options.seed);
  report.frames_balanced = balanced.size();
  const Frames frames = Load(balanced);

  std::mt19937_64 rng(options.seed);
  torch::manual_seed(options.seed);
  std::vector<std::size_t> order(balanced.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  const auto n_val = static_cast<std::size_t>(
      std::floor(options.validation_share * static_cast<double>(order.size())));
  const std::vector<std::size_t> validation(order.begin(),
                                            order.begin() + static_cast<long>(n_val));
  std::vector<std::size_t> training(order.begin() + static_cast<long>(n_val), order.end());
  AUTODRIVE_THROW_UNLESS(!training.empty(), "too few frames to train on: " << balanced.size());
  report.frames_validation = validation.size();

  torch::optim::Adam adam(net->parameters(), torch::optim::AdamOptions(options.learning_rate));
  const auto batch = static_cast<std::size_t>(options.batch_size);
  const std::size_t batches = (training.size() + batch - 1) / batch;
  for (int epoch = 1; epoch <= options.epochs; ++epoch) {
    const auto e0 = std::chrono::steady_clock::now();
    net->train();
    std::shuffle(training.begin(), training.end(), rng);
    double sum = 0;
    for (std::size_t b = 0; b < batches; ++b) {
      const std::size_t from = b * batch, to = std::min(training.size(), from + batch);
      const torch::Tensor x = Batch(frames, training, from, to, options.augment, rng);
      const torch::Tensor y = Labels(frames, training, from, to);
      adam.zero_grad();
      const torch::Tensor loss = torch::mse_loss(net->forward(x), y);
      loss.backward();
      adam.step();
      sum += loss.item<double>();
      if (progress) progress(epoch, b + 1, batches);
    }
    EpochReport e;
    e.epoch = epoch;
    e.train_loss = sum / static_cast<double>(batches);
    net->eval();
    if (!validation.empty()) {
      const torch::NoGradGuard no_grad;
      double v = 0;
      for (std::size_t from = 0; from < validation.size(); from += batch) {
        const std::size_t to = std::min(validation.size(), from + batch);
        const torch::Tensor x = Batch(frames, validation, from, to, false, rng);
        const torch::Tensor y = Labels(frames, validation, from, to);
        v += torch::mse_loss(net->forward(x), y, torch::Reduction::Sum).item<double>();
      }
      e.validation_loss = v / (2.0 * static_cast<double>(validation.size()));
    }
    e.seconds = Since(e0);
    report.epochs.push_back(e);
  }
  net->eval();
  report.seconds = Since(t0);
  return report;
}

}  // namespace autodrive::examples::cloning
