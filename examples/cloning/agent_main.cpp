// autodrive-example-cloning: the behavioural-cloning case study's driving agent: each new frame
// of the car's front camera through the trained network (model.h) to its throttle and
// steering. Public topics only: the car's front_camera, throttle_command and steering_command.
// See README.md.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/dds/conversions.h"
#include "common/dds/participant.h"
#include "common/dds/program_options.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/error.h"
#include "common/logging.h"
#include "common/shutdown.h"
#include "examples/cloning/model.h"
#include "examples/common/agent_options.h"
#include "examples/common/car_io.h"

int main(int argc, char** argv) {
  using namespace autodrive;
  using namespace autodrive::examples::cloning;
  CLI::App app{
      "autodrive-example-cloning: drives one car from its front camera alone with a model "
      "trained by autodrive-example-cloning-train (the paper's behavioural cloning). Public "
      "topics only: front_camera in, throttle_command and steering_command out. See "
      "examples/cloning/README.md."};
  std::string vehicle, model;
  double max_throttle = 1.0;
  int threads = 1;
  std::string save_frames;
  examples::AgentOptions agent("/autodrive/example_cloning", 30.0);
  app.add_option("--vehicle", vehicle, "the car to drive: nigel_<n>")->required();
  app.add_option("--model", model,
                 "the model file (default: $AUTODRIVE_CLONING_MODEL, which a scenario's agent "
                 "inherits from the runner)");
  app.add_option("--max-throttle", max_throttle, "the throttle is clamped to [0, this]")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--threads", threads, "libtorch's threads for inference")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--save-frames", save_frames,
                 "write each frame it drove on to this folder as frame_NNNNNN.png with "
                 "commands.csv (what the model saw and said)");
  agent.Add(app);
  CLI11_PARSE(app, argc, argv);
  // The signals first, before anything can start a thread (agent_options.h).
  std::atomic<bool> stop{false};
  ShutdownSignals signals([&] { stop.store(true); });
  try {
    InitLogging("autodrive-example-cloning", ParseLogLevel(agent.log_level));
    if (model.empty()) {
      const char* from_env = std::getenv("AUTODRIVE_CLONING_MODEL");
      if (from_env == nullptr || *from_env == '\0') {
        throw InputError("give --model FILE or set AUTODRIVE_CLONING_MODEL");
      }
      model = from_env;
    }
    torch::set_num_threads(threads);
    const VehicleId id = ParseVehicleName(vehicle);
    CloningNet net;
    LoadModel(net, model);
    net->eval();
    spdlog::info("{}: driving with the model {}", vehicle, model);

    dds::Participant participant(agent.dds.Participant());
    examples::CarIo io(participant, id, examples::PoseSource::kIps);
    dds::Reader<msg::Image> camera(participant, dds::topics::FrontCamera(id));

    std::ofstream commands;
    if (!save_frames.empty()) {
      std::filesystem::create_directories(save_frames);
      commands.open(std::filesystem::path(save_frames) / "commands.csv");
      if (!commands) throw InputError(save_frames + ": cannot write commands.csv there");
      commands << "frame,stamp_s,throttle,steering\n";
    }
    double throttle = 0.0, steering = 0.0;
    std::vector<double> inference_ms;
    std::size_t refused = 0;
    const auto decide = [&](Time now) {
      io.Take();  // (the pose and scan, which this agent does not use)
      // The newest frame only: a model that falls behind drives on the latest view.
      std::optional<dds::Message<msg::Image>> newest;
      while (auto m = camera.TakeOne()) newest = std::move(m);
      if (newest) {
        const msg::Image& m = **newest;
        const std::string_view encoding = dds::View(m.encoding);
        const bool rgb = encoding == "rgb8", bgr = encoding == "bgr8";
        if (!(rgb || bgr) || m.step < m.width * 3 ||
            m.data._length < static_cast<std::size_t>(m.step) * m.height) {
          if (refused++ % 100 == 0) {
            spdlog::warn("{}: refused a {}x{} frame of encoding \"{}\" (rgb8 or bgr8)", vehicle,
                         m.width, m.height, encoding);
          }
        } else {
          const auto t0 = std::chrono::steady_clock::now();
          const cv::Mat view(static_cast<int>(m.height), static_cast<int>(m.width), CV_8UC3,
                             m.data._buffer, m.step);
          cv::Mat frame = view;
          if (bgr) cv::cvtColor(view, frame, cv::COLOR_BGR2RGB);
          const torch::InferenceMode inference;
          const torch::Tensor out = net->forward(Preprocess(frame).unsqueeze(0));
          throttle = std::clamp(out[0][0].item<double>(), 0.0, max_throttle);
          steering = std::clamp(out[0][1].item<double>(), -1.0, 1.0);
          inference_ms.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count());
          if (commands.is_open()) {
            const std::size_t n = inference_ms.size() - 1;
            char name[32];
            std::snprintf(name, sizeof name, "frame_%06zu.png", n);
            cv::Mat bgr_frame;
            cv::cvtColor(frame, bgr_frame, cv::COLOR_RGB2BGR);
            cv::imwrite((std::filesystem::path(save_frames) / name).string(), bgr_frame);
            commands << n << ',' << ToSeconds(now.time_since_epoch()) << ',' << throttle << ','
                     << steering << '\n';
          }
        }
      }
      io.Command(throttle, steering);
    };
    const int code = io.Run(participant, agent.lockstep, agent.rate_hz, decide, stop);
    io.Command(0.0, 0.0);
    if (!inference_ms.empty()) {
      std::vector<double> sorted = inference_ms;
      std::sort(sorted.begin(), sorted.end());
      double mean = 0;
      for (const double v : sorted) mean += v;
      mean /= static_cast<double>(sorted.size());
      spdlog::info(
          "{}: {} frames through the network on {} thread(s): {:.2f} ms mean, {:.2f} ms p95 "
          "({:.0f} frames a second)",
          vehicle, sorted.size(), threads, mean, sorted[sorted.size() * 95 / 100], 1000.0 / mean);
    }
    return code;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autodrive-example-cloning: %s\n", e.what());
    return 1;
  }
}
