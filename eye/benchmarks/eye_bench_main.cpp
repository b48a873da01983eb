// autodrive-bench-eye: the Eye's speed on one core. Four cars drive circles under a camera
// straight down (tags drawn by eye/testing, 6 reference tags on the floor); per resolution:
// frames per second of the localiser tracking them (regions around the predicted tags, a full
// scan every second), of plain full-frame AprilTag detection of the same frames, and the
// ratio. Then end to end on DDS: frames published as a camera's image topic (rgb8, stamped
// when published), `EyeService` localising them, and the time from a frame's stamp to its
// fleet message arriving in this process. Goals: >= 60 fps at 1920x1080 tracking, >= 3x the
// full-frame rate, latency p99 <= 30 ms.
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgproc.hpp>

#include "common/camera/camera_model.h"
#include "common/cpu_time.h"
#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "eye/detector.h"
#include "eye/localizer.h"
#include "eye/service.h"
#include "eye/testing/synthetic_scene.h"

namespace {

using namespace autodrive;
using namespace autodrive::eye;

struct Scene {
  camera::Camera camera;
  EyeConfig config;
  std::vector<testing::PlacedTag> references;
};

// A camera `height_m` over the middle of a 5 m square, six reference tags, four cars.
Scene MakeScene(int width, int height, double f_px, double height_m,
                const std::filesystem::path& dir) {
  Scene s{testing::OverheadCamera(2.5, 2.5, height_m, f_px, width, height), {}, {}};
  const auto calibration = dir / ("camera_" + std::to_string(width) + ".yaml");
  camera::SaveOpenCvCalibration(calibration, s.camera.model.intrinsics());
  s.config.cameras.push_back(
      {"overhead", "topic:bench_overhead", calibration.string(), std::nullopt, 30.0, 0.0});
  for (int i = 1; i <= 4; ++i) {
    VehicleTagConfig v;
    v.name = "nigel_" + std::to_string(i);
    v.tag_id = i;
    s.config.vehicles.push_back(v);
  }
  const double refs[6][3] = {{100, 0.5, 0.5}, {101, 4.5, 4.5}, {102, 4.5, 0.5},
                             {103, 0.5, 4.5}, {104, 1.5, 3.5}, {105, 3.5, 1.5}};
  for (const auto& r : refs) {
    ReferenceTagConfig ref;
    ref.id = static_cast<int>(r[0]);
    ref.x_m = r[1];
    ref.y_m = r[2];
    s.config.reference_tags.push_back(ref);
    s.references.push_back({"tag36h11", ref.id, 0.0762, testing::FlatTagPose(r[1], r[2], 0, 0)});
  }
  s.config.registration.frames = 1;
  return s;
}

// Frame k: four cars on circles of 0.6 m about four centres, 0.2 m/s, at 30 Hz.
cv::Mat DrawFrame(const Scene& s, int k) {
  std::vector<testing::PlacedTag> tags = s.references;
  const double centres[4][2] = {{1.3, 1.3}, {3.7, 1.3}, {1.3, 3.7}, {3.7, 3.7}};
  for (int i = 0; i < 4; ++i) {
    // The rear axle on the circle, the heading its tangent, the tag 7.077 cm ahead of it.
    const double a = 0.2 / 0.6 * k / 30.0 + i;
    const double yaw = a + kPi / 2;
    const double x = centres[i][0] + 0.6 * std::cos(a) + 0.07077 * std::cos(yaw);
    const double y = centres[i][1] + 0.6 * std::sin(a) + 0.07077 * std::sin(yaw);
    tags.push_back({"tag36h11", i + 1, 0.0762, testing::FlatTagPose(x, y, 0.257, yaw - kPi / 2)});
  }
  return testing::DrawScene(s.camera, tags);
}

void Resolution(const char* label, int width, int height, double f_px, double height_m, int frames,
                const std::filesystem::path& dir) {
  const Scene s = MakeScene(width, height, f_px, height_m, dir);
  std::fprintf(stderr, "drawing %d frames of %dx%d ...\n", frames, width, height);
  std::vector<cv::Mat> images;
  for (int k = 0; k < frames; ++k) images.push_back(DrawFrame(s, k));
  // Tracking: the localiser as it runs (register on the first frame, then regions).
  Localizer localizer(s.config);
  std::vector<EyeEvent> events;
  double tracked_cpu = 0;
  int tracked_frames = 0, localised = 0;
  for (int k = 0; k < frames; ++k) {
    const double t0 = ThreadCpuSeconds();
    const auto cars = localizer.LocalizeFrame(0, TimeFromSeconds(k / 30.0),
                                              images[static_cast<std::size_t>(k)], &events);
    const double dt = ThreadCpuSeconds() - t0;
    if (k < 2) continue;  // registration and the first full scan after it
    tracked_cpu += dt;
    ++tracked_frames;
    localised += static_cast<int>(cars.size());
  }
  // Plain full-frame detection of the same frames.
  TagDetector detector(s.config.detector);
  double full_cpu = 0;
  int full_found = 0;
  for (int k = 2; k < frames; ++k) {
    const double t0 = ThreadCpuSeconds();
    full_found += static_cast<int>(detector.Detect(images[static_cast<std::size_t>(k)]).size());
    full_cpu += ThreadCpuSeconds() - t0;
  }
  const double tracked_fps = tracked_frames / tracked_cpu;
  const double full_fps = (frames - 2) / full_cpu;
  const LocalizerCounters n = localizer.counters();
  std::printf(
      "%-10s tracking 4 cars: %7.1f fps (%.2f ms/frame; %.2f cars per frame, %lld full "
      "scans, %lld outliers, %lld refused, %.1f%% of the pixels searched); full-frame detection: "
      "%6.1f fps (%.2f "
      "ms/frame, %.1f tags per frame); ratio %.1fx\n",
      label, tracked_fps, 1e3 / tracked_fps, static_cast<double>(localised) / tracked_frames,
      n.full_scans, n.outliers, n.refused_poses,
      100.0 * static_cast<double>(n.pixels_searched) /
          (static_cast<double>(frames) * width * height),
      full_fps, 1e3 / full_fps, static_cast<double>(full_found) / (frames - 2),
      tracked_fps / full_fps);
}

void Latency(int frames, const std::filesystem::path& dir) {
  const Scene s = MakeScene(1920, 1080, 626.0, 3.0, dir);
  // Every frame drawn beforehand (6 MB each), so that the cars move on smoothly throughout.
  std::fprintf(stderr, "drawing %d frames for the DDS run ...\n", frames);
  std::vector<cv::Mat> rgb;
  for (int k = 0; k < frames; ++k) {
    cv::Mat colour;
    cv::cvtColor(DrawFrame(s, k), colour, cv::COLOR_GRAY2RGB);
    rgb.push_back(colour);
  }
  const std::string partition = "bench_eye_" + std::to_string(::getpid());
  dds::Participant participant(dds::ParticipantOptions{{}, partition, {}});
  dds::Writer<msg::Image> camera(participant, dds::topics::OverheadCamera("bench_overhead"));
  dds::Reader<msg::FleetState> fleet(participant, dds::topics::EyeFleet());
  EyeService service(s.config, participant);
  camera.WaitForReaders(1, std::chrono::seconds(10));
  std::vector<double> latency_ms;
  const auto start = std::chrono::steady_clock::now();
  int sent = 0;
  while (sent < frames) {
    const auto due = start + std::chrono::milliseconds(1000 * sent / 30);
    // Take the fleet messages that arrived while waiting for the next frame's time.
    while (std::chrono::steady_clock::now() < due) {
      fleet.WaitForData(std::chrono::milliseconds(2));
      while (auto m = fleet.TakeOne()) {
        latency_ms.push_back(ToSeconds(SystemNow() - dds::FromMsg((*m)->header.stamp)) * 1e3);
      }
    }
    const cv::Mat& image = rgb[static_cast<std::size_t>(sent)];
    msg::Image m{};
    m.header.stamp = dds::ToMsg(SystemNow());
    dds::BorrowString(m.header.frame_id, "bench_overhead");
    m.width = static_cast<std::uint32_t>(image.cols);
    m.height = static_cast<std::uint32_t>(image.rows);
    dds::BorrowString(m.encoding, "rgb8");
    m.step = static_cast<std::uint32_t>(image.step[0]);
    dds::BorrowSequence(m.data, std::span<std::uint8_t>(image.data, image.total() * 3));
    camera.Write(m);
    ++sent;
  }
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
  while (std::chrono::steady_clock::now() < end) {
    fleet.WaitForData(std::chrono::milliseconds(10));
    while (auto m = fleet.TakeOne()) {
      latency_ms.push_back(ToSeconds(SystemNow() - dds::FromMsg((*m)->header.stamp)) * 1e3);
    }
  }
  service.Stop();
  std::sort(latency_ms.begin(), latency_ms.end());
  const auto at = [&](double q) {
    return latency_ms.empty()
               ? 0.0
               : latency_ms[std::min(
                     latency_ms.size() - 1,
                     static_cast<std::size_t>(q * static_cast<double>(latency_ms.size())))];
  };
  const ServiceCounters c = service.counters();
  std::printf(
      "end to end on DDS, 1920x1080 rgb8 at 30 Hz, %d frames: %zu fleet messages; frame "
      "stamp to fleet message received p50 %.1f ms, p99 %.1f ms, max %.1f ms (%llu "
      "frames dropped by the Eye)\n",
      sent, latency_ms.size(), at(0.5), at(0.99), latency_ms.empty() ? 0.0 : latency_ms.back(),
      static_cast<unsigned long long>(c.dropped_frames));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "autodrive-bench-eye: the Eye's speed on one core (tracking vs full-frame "
      "detection) and its end-to-end latency on DDS (docs/eye.md)"};
  int frames = 150;
  int dds_frames = 300;
  app.add_option("--frames", frames, "frames per resolution")->check(CLI::Range(10, 100000));
  app.add_option("--dds-frames", dds_frames, "frames of the DDS run (30 Hz)")
      ->check(CLI::Range(10, 100000));
  CLI11_PARSE(app, argc, argv);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("autodrive_bench_eye_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::printf("the Eye, one thread for the localiser, four cars at 0.2 m/s, tag36h11 76.2 mm\n");
  // 1280x720 from 2.3 m and 1920x1080 from 3 m: tags of 14-17 px, the whole 5 m square in view.
  Resolution("1280x720", 1280, 720, 417.0, 2.3, frames, dir);
  Resolution("1920x1080", 1920, 1080, 626.0, 3.0, frames, dir);
  Latency(dds_frames, dir);
  std::printf(
      "goals: >= 60 fps at 1920x1080 tracking, >= 3x the full-frame rate, latency p99 <= "
      "30 ms\n");
  std::filesystem::remove_all(dir);
  return 0;
}
