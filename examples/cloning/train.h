#pragma once
/// @file
/// Training the behavioural-cloning network (model.h) on recorded driving data sets
/// (dataset.h): balanced, augmented, Adam, mean squared error on throttle and steering.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <vector>

#include "examples/cloning/model.h"

namespace autodrive::examples::cloning {

struct TrainOptions {
  int epochs = 4;               ///< the paper's
  double learning_rate = 1e-3;  ///< Adam's, the paper's
  int batch_size = 16;
  double validation_share = 0.1;  ///< frames held out (at random) to measure the fit
  int balance_bins = 21;          ///< `Balance`'s bins and cap factor
  double balance_factor = 1.5;
  bool augment = true;
  std::uint64_t seed = 1;
};

struct EpochReport {
  int epoch = 0;
  double train_loss = 0.0;       ///< mean squared error over the epoch's batches
  double validation_loss = 0.0;  ///< on the held-out frames, without augmentation
  double seconds = 0.0;          ///< wall time of the epoch
};

struct TrainReport {
  std::size_t frames_read = 0;
  std::size_t frames_balanced = 0;  ///< after `Balance`
  std::size_t frames_validation = 0;
  std::vector<EpochReport> epochs;
  double seconds = 0.0;  ///< wall time, reading the frames included
};

/// Trains `net` (its weights as they are: seed libtorch before making it for reproducible
/// initial weights) on the frames of `folders`. `progress(epoch, batches_done, batches_total)` is
/// called after each batch. @throws InputError as `ReadDrivingDataset`.
TrainReport Train(CloningNet& net, const std::vector<std::filesystem::path>& folders,
                  const TrainOptions& options,
                  const std::function<void(int, std::size_t, std::size_t)>& progress = {});

}  // namespace autodrive::examples::cloning
