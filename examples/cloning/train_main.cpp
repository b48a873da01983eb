// autodrive-example-cloning-train: trains the behavioural-cloning network (model.h) on driving
// data sets that `autodrive-sim record` wrote, and writes the model. See README.md.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common/error.h"
#include "examples/cloning/train.h"

int main(int argc, char** argv) {
  using namespace autodrive::examples::cloning;
  CLI::App app{
      "autodrive-example-cloning-train: trains the paper's 6-layer CNN (front camera frame to "
      "throttle and steering) on data sets recorded with autodrive-sim record: steering "
      "balanced, frames augmented (light), Adam, 4 epochs; writes the model for "
      "autodrive-example-cloning. See examples/cloning/README.md."};
  std::vector<std::string> data;
  std::string out;
  TrainOptions options;
  int threads = 0;
  bool quiet = false;
  app.add_option("--data", data, "data set folders (frame_NNNNNN.png and labels.csv)")
      ->required()
      ->delimiter(',')
      ->check(CLI::ExistingDirectory);
  app.add_option("--out", out, "the model file to write")->required();
  app.add_option("--epochs", options.epochs)->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--learning-rate", options.learning_rate, "Adam's")
      ->check(CLI::Range(1e-7, 1.0))
      ->capture_default_str();
  app.add_option("--batch", options.batch_size)->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--validation", options.validation_share, "share of frames held out")
      ->check(CLI::Range(0.0, 0.5))
      ->capture_default_str();
  app.add_option("--balance-factor", options.balance_factor,
                 "each steering bin keeps at most this many times the mean bin's frames")
      ->check(CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  app.add_flag(
      "--no-augment", [&](std::int64_t) { options.augment = false; },
      "train on the frames as recorded");
  app.add_option("--seed", options.seed, "shuffling, balancing, augmentation, initial weights")
      ->capture_default_str();
  app.add_option("--threads", threads, "libtorch's threads (0: its default)")
      ->check(CLI::Range(0, 256))
      ->capture_default_str();
  app.add_flag("-q,--quiet", quiet, "no progress on stderr");
  CLI11_PARSE(app, argc, argv);
  try {
    if (threads > 0) torch::set_num_threads(threads);
    std::vector<std::filesystem::path> folders(data.begin(), data.end());
    const bool tty = isatty(fileno(stderr)) != 0;
    const auto progress = [&](int epoch, std::size_t done, std::size_t total) {
      if (quiet || !tty) return;
      std::fprintf(stderr, "\repoch %d: batch %zu / %zu", epoch, done, total);
    };
    torch::manual_seed(options.seed);  // the initial weights
    CloningNet net;
    const TrainReport r = Train(net, folders, options, progress);
    SaveModel(net, out);
    if (!quiet && tty) std::fprintf(stderr, "\r");
    std::printf("frames: %zu read, %zu after balancing, %zu held out\n", r.frames_read,
                r.frames_balanced, r.frames_validation);
    for (const EpochReport& e : r.epochs) {
      std::printf("epoch %d: training loss %.5f, validation loss %.5f, %.1f s\n", e.epoch,
                  e.train_loss, e.validation_loss, e.seconds);
    }
    std::printf("trained in %.1f s on %d threads; model written to %s\n", r.seconds,
                torch::get_num_threads(), out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-example-cloning-train: %s\n", e.what());
    return 1;
  }
}
