#include "eye/service.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <span>
#include <thread>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "eye/localizer.h"
#include "eye/sources.h"

namespace autodrive::eye {

namespace {

using SteadyClock = std::chrono::steady_clock;

// A camera whose frames stop for this long is lost.
constexpr auto kCameraLostAfter = std::chrono::seconds(2);

}  // namespace

struct EyeService::Impl {
  const dds::Participant& participant;
  Localizer localizer;
  dds::Writer<msg::FleetState> fleet_writer;
  dds::Writer<msg::Event> event_writer;
  std::vector<std::unique_ptr<dds::Writer<msg::Point>>> ips_writers;  // per vehicle, or empty
  // Per camera, when outputs.debug_image_rate_hz > 0: its writer and when it last wrote.
  std::vector<std::unique_ptr<dds::Writer<msg::Image>>> debug_writers;
  std::vector<SteadyClock::time_point> debug_last;
  std::atomic<bool> stop{false};
  std::atomic<int> files_running{0};

  std::mutex queue_mutex;
  std::condition_variable queue_cv;
  std::deque<FrameDetections> queue;

  mutable std::mutex counters_mutex;
  ServiceCounters counters;
  std::vector<double> latencies_ms;  // a ring of the last kLatencies
  std::size_t latency_next = 0;
  static constexpr std::size_t kLatencies = 10000;
  std::uint64_t event_id = 0;

  dds::Message<msg::FleetState> fleet_message;
  std::vector<std::jthread> threads;

  // Lockstep: each camera's reader, and what its silence was last judged on.
  struct SteppedCamera {
    std::unique_ptr<dds::Reader<msg::Image>> reader;
    dds::Message<msg::Image> sample;
    std::optional<Time> last_frame;
    bool lost = false;
  };
  std::vector<SteppedCamera> stepped;
  std::vector<FrameDetections> step_frames;  // scratch
  std::vector<EyeEvent> fuse_events;         // scratch of `Fuse` (one thread: the fusing one)

  Impl(const EyeConfig& config, const dds::Participant& p, EyeMode mode)
      : participant(p),
        localizer(config),
        fleet_writer(p, dds::topics::EyeFleet()),
        event_writer(p, dds::topics::EyeEvents()) {
    if (config.outputs.ips) {
      for (const VehicleTagConfig& v : config.vehicles) {
        ips_writers.push_back(
            std::make_unique<dds::Writer<msg::Point>>(p, dds::topics::Ips(v.id())));
      }
    }
    for (const CameraConfig& cam : config.cameras) {
      if (config.outputs.debug_image_rate_hz > 0) {
        debug_writers.push_back(
            std::make_unique<dds::Writer<msg::Image>>(p, dds::topics::EyeDebugImage(cam.name)));
      }
    }
    debug_last.assign(config.cameras.size(), SteadyClock::time_point{});
    if (mode == EyeMode::kLockstep) {
      for (const CameraConfig& cam : config.cameras) {
        AUTODRIVE_THROW_UNLESS(cam.source.rfind("topic:", 0) == 0,
                               "camera " << cam.name << ": in lockstep the Eye reads simulated "
                                         << "cameras only (source topic:NAME), not " << cam.source);
        stepped.push_back({std::make_unique<dds::Reader<msg::Image>>(
                               p, dds::topics::OverheadCamera(cam.source.substr(6))),
                           {},
                           std::nullopt,
                           false});
      }
      return;
    }
    for (std::size_t c = 0; c < config.cameras.size(); ++c) {
      const CameraConfig& cam = config.cameras[c];
      if (cam.source.rfind("topic:", 0) == 0) {
        auto reader = std::make_shared<dds::Reader<msg::Image>>(
            p, dds::topics::OverheadCamera(cam.source.substr(6)));
        threads.emplace_back([this, c, reader] { TopicCamera(c, *reader); });
      } else {
        std::shared_ptr<FrameSource> source = OpenSource(cam);
        const bool files =
            cam.source.rfind("images:", 0) == 0 || cam.source.rfind("video:", 0) == 0;
        if (files) ++files_running;
        threads.emplace_back([this, c, source, files] { SourceCamera(c, *source, files); });
      }
    }
    threads.emplace_back([this] { FuseLoop(); });
  }

  ~Impl() { StopThreads(); }

  void StopThreads() {
    stop.store(true);
    queue_cv.notify_all();
    threads.clear();  // joins
  }

  void Publish(const EyeEvent& e) {
    msg::Event m{};
    m.header.stamp = dds::ToMsg(e.stamp);
    dds::BorrowString(m.header.frame_id, "map");
    m.event_id = ++event_id;
    const bool warning =
        !e.cleared &&
        (e.kind == EyeEvent::Kind::kCameraMoved || e.kind == EyeEvent::Kind::kCameraLost ||
         e.kind == EyeEvent::Kind::kVehicleLost || e.kind == EyeEvent::Kind::kTagMounting ||
         e.kind == EyeEvent::Kind::kDuplicateTag);
    m.severity = warning ? 2 : 1;  // Event_Constants WARNING, INFO
    dds::BorrowString(m.source, "eye");
    dds::BorrowString(m.code, ToString(e.kind));
    dds::BorrowString(m.message, e.text.c_str());
    dds::BorrowString(m.device_id, e.subject.c_str());
    m.active = warning;
    event_writer.Write(m);
    spdlog::log(warning ? spdlog::level::warn : spdlog::level::info, "{} {}: {}", ToString(e.kind),
                e.subject, e.text);
  }

  void Push(FrameDetections&& d) {
    {
      const std::lock_guard lock(queue_mutex);
      queue.push_back(std::move(d));
    }
    queue_cv.notify_one();
  }

  // The frame with its tags drawn: cars' in green with their names, reference tags in blue,
  // unknown ones in red; published as rgb8.
  void PublishDebugImage(std::size_t camera, Time stamp, const cv::Mat& image,
                         const FrameDetections& d) {
    const EyeConfig& config = localizer.config();
    cv::Mat rgb;
    if (image.channels() == 1) {
      cv::cvtColor(image, rgb, cv::COLOR_GRAY2RGB);
    } else {
      rgb = image.clone();
    }
    for (const TagDetection& t : d.tags) {
      cv::Scalar colour(255, 60, 60);
      std::string label = std::to_string(t.id);
      for (const VehicleTagConfig& v : config.vehicles) {
        if (v.tag_id == t.id) {
          colour = cv::Scalar(40, 220, 40);
          label = v.name;
        }
      }
      for (const ReferenceTagConfig& r : config.reference_tags) {
        if (r.id == t.id) colour = cv::Scalar(60, 120, 255);
      }
      std::vector<cv::Point> quad;
      for (const Eigen::Vector2d& c : t.corners_px) {
        quad.emplace_back(static_cast<int>(std::lround(c.x())),
                          static_cast<int>(std::lround(c.y())));
      }
      cv::polylines(rgb, quad, true, colour, 2);
      cv::putText(rgb, label, quad[3] + cv::Point(0, 16), cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1);
    }
    msg::Image m{};
    m.header.stamp = dds::ToMsg(stamp);
    dds::BorrowString(m.header.frame_id, config.cameras[camera].name.c_str());
    m.width = static_cast<std::uint32_t>(rgb.cols);
    m.height = static_cast<std::uint32_t>(rgb.rows);
    dds::BorrowString(m.encoding, "rgb8");
    m.step = static_cast<std::uint32_t>(rgb.step[0]);
    dds::BorrowSequence(m.data, std::span<std::uint8_t>(rgb.data, rgb.total() * 3));
    debug_writers[camera]->Write(m);
  }

  // Searches one frame; nothing when it cannot be searched (bad size, OpenCV refusing it):
  // counted, never fatal.
  std::optional<FrameDetections> Search(std::size_t camera, Time stamp, const cv::Mat& image) {
    try {
      FrameDetections d = localizer.Detect(camera, stamp, image);
      if (!debug_writers.empty()) {
        const auto now = SteadyClock::now();
        if (now - debug_last[camera] >=
            std::chrono::duration<double>(1.0 / localizer.config().outputs.debug_image_rate_hz)) {
          debug_last[camera] = now;
          PublishDebugImage(camera, stamp, image, d);
        }
      }
      const std::lock_guard lock(counters_mutex);
      ++counters.frames;
      return d;
    } catch (const std::exception& e) {
      const std::lock_guard lock(counters_mutex);
      if (counters.bad_frames++ % 100 == 0) spdlog::warn("camera {}: {}", camera, e.what());
      return std::nullopt;
    }
  }

  void Detect(std::size_t camera, Time stamp, const cv::Mat& image) {
    if (std::optional<FrameDetections> d = Search(camera, stamp, image)) Push(std::move(*d));
  }

  // A frame of an image topic as a grey image (a view when it is mono8); nothing when its
  // encoding or size is refused (counted, logged every 100).
  std::optional<cv::Mat> Grey(std::size_t camera, const msg::Image& m) {
    const std::string_view encoding = dds::View(m.encoding);
    const bool rgb = encoding == "rgb8", bgr = encoding == "bgr8", mono = encoding == "mono8";
    const std::size_t channels = mono ? 1 : 3;
    if (!(rgb || bgr || mono) || m.step < m.width * channels ||
        m.data._length < static_cast<std::size_t>(m.step) * m.height) {
      const std::lock_guard lock(counters_mutex);
      if (counters.bad_frames++ % 100 == 0) {
        spdlog::warn("camera {}: refused a {}x{} frame of encoding \"{}\" (rgb8, bgr8 or mono8)",
                     localizer.config().cameras[camera].name, m.width, m.height, encoding);
      }
      return std::nullopt;
    }
    const cv::Mat view(static_cast<int>(m.height), static_cast<int>(m.width),
                       mono ? CV_8UC1 : CV_8UC3, m.data._buffer, m.step);
    if (mono) return view;
    cv::Mat grey;
    cv::cvtColor(view, grey, rgb ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
    return grey;
  }

  // A camera's frames stopped (`lost`) or came again after `silent` (published as the lost
  // event cleared).
  void CameraSilence(std::size_t camera, Time at, bool lost, Duration silent) {
    const std::string& name = localizer.config().cameras[camera].name;
    EyeEvent e{EyeEvent::Kind::kCameraLost, at, name,
               lost ? fmt::format("no frame for {:.0f} s", ToSeconds(kCameraLostAfter))
                    : fmt::format("frames again after {:.1f} s", ToSeconds(silent))};
    e.cleared = !lost;
    Publish(e);
  }

  // A simulated (or ROS) camera's image topic: the newest frame each time, older ones dropped.
  void TopicCamera(std::size_t camera, dds::Reader<msg::Image>& reader) {
    dds::Message<msg::Image> sample;
    auto last_frame = SteadyClock::now();
    bool had_frames = false, lost = false;
    const std::string name = localizer.config().cameras[camera].name;
    while (!stop.load()) {
      if (!reader.WaitForData(std::chrono::milliseconds(100))) {
        if (had_frames && !lost && SteadyClock::now() - last_frame > kCameraLostAfter) {
          lost = true;
          CameraSilence(camera, SystemNow(), true, {});
        }
        continue;
      }
      int taken = 0;
      while (reader.TakeOne(sample)) ++taken;
      if (taken == 0) continue;
      if (taken > 1) {
        const std::lock_guard lock(counters_mutex);
        counters.dropped_frames += static_cast<std::uint64_t>(taken - 1);
      }
      const auto now = SteadyClock::now();
      if (lost) {
        CameraSilence(camera, SystemNow(), false,
                      std::chrono::duration_cast<Duration>(now - last_frame));
      }
      last_frame = now;
      had_frames = true;
      lost = false;
      if (const std::optional<cv::Mat> grey = Grey(camera, *sample)) {
        Detect(camera, dds::FromMsg(sample->header.stamp), *grey);
      }
    }
  }

  // Lockstep: every frame that came, searched camera by camera, fused in stamp order.
  void Step(Time now) {
    step_frames.clear();
    for (std::size_t c = 0; c < stepped.size(); ++c) {
      SteppedCamera& cam = stepped[c];
      while (cam.reader->TakeOne(cam.sample)) {
        Time stamp;
        try {
          stamp = dds::FromMsg(cam.sample->header.stamp);
        } catch (const InputError&) {
          const std::lock_guard lock(counters_mutex);
          ++counters.bad_frames;
          continue;
        }
        if (cam.lost) CameraSilence(c, now, false, stamp - *cam.last_frame);
        cam.lost = false;
        cam.last_frame = stamp;
        const std::optional<cv::Mat> grey = Grey(c, *cam.sample);
        if (!grey) continue;
        if (std::optional<FrameDetections> d = Search(c, stamp, *grey)) {
          step_frames.push_back(std::move(*d));
        }
      }
      if (cam.last_frame && !cam.lost && now - *cam.last_frame > kCameraLostAfter) {
        cam.lost = true;
        CameraSilence(c, now, true, {});
      }
    }
    std::stable_sort(
        step_frames.begin(), step_frames.end(),
        [](const FrameDetections& a, const FrameDetections& b) { return a.stamp < b.stamp; });
    for (const FrameDetections& frame : step_frames) Fuse(frame);
    Expire(now);
  }

  bool WaitForAcks(std::chrono::steady_clock::duration timeout) const {
    bool all = fleet_writer.WaitForAcks(timeout) && event_writer.WaitForAcks(timeout);
    for (const auto& w : ips_writers) all = w->WaitForAcks(timeout) && all;
    return all;
  }

  // Files, a device or a stream. Files are paced at the camera's rate and stamped from the
  // service's start, as a live camera would be.
  void SourceCamera(std::size_t camera, FrameSource& source, bool files) {
    const Time start_wall = SystemNow();
    const auto start = SteadyClock::now();
    const double rate = localizer.config().cameras[camera].rate_hz;
    try {
      while (!stop.load()) {
        auto frame = source.Next();
        if (!frame) break;
        if (files) {
          const auto due =
              start + std::chrono::duration_cast<SteadyClock::duration>(
                          std::chrono::duration<double>(static_cast<double>(frame->index) / rate));
          while (!stop.load() && SteadyClock::now() < due) {
            std::this_thread::sleep_for(std::min<SteadyClock::duration>(
                due - SteadyClock::now(), std::chrono::milliseconds(50)));
          }
          frame->stamp = start_wall + FromSeconds(static_cast<double>(frame->index) / rate);
        }
        if (!frame->unreadable.empty()) {
          // Counted and skipped; the camera goes on with its next frame.
          const std::lock_guard lock(counters_mutex);
          if (counters.unreadable_frames++ % 100 == 0) {
            spdlog::warn("camera {}: {} skipped: {} ({} unreadable so far)",
                         localizer.config().cameras[camera].name, frame->name, frame->unreadable,
                         counters.unreadable_frames);
          }
          continue;
        }
        Detect(camera, frame->stamp, frame->image);
      }
    } catch (const std::exception& e) {
      spdlog::error("camera {}: {}", localizer.config().cameras[camera].name, e.what());
    }
    if (files) --files_running;
  }

  // With no frame for a while (every camera silent), the cars' tracks still end: on the
  // cameras' clock, run on from the newest frame's stamp by the wall time since it came.
  void FuseLoop() {
    std::optional<Time> newest;
    SteadyClock::time_point newest_arrival;
    while (true) {
      FrameDetections frame;
      {
        std::unique_lock lock(queue_mutex);
        const bool got = queue_cv.wait_for(lock, std::chrono::milliseconds(200),
                                           [&] { return stop.load() || !queue.empty(); });
        if (stop.load()) return;
        if (!got) {
          lock.unlock();
          if (newest) {
            Expire(*newest +
                   std::chrono::duration_cast<Duration>(SteadyClock::now() - newest_arrival));
          }
          continue;
        }
        frame = std::move(queue.front());
        queue.pop_front();
      }
      if (!newest || frame.stamp > *newest) {
        newest = frame.stamp;
        newest_arrival = SteadyClock::now();
      }
      Fuse(frame);
    }
  }

  // Ends the tracks of cars not seen for the tracking's lost_after_s at `now`.
  void Expire(Time now) {
    fuse_events.clear();
    localizer.ExpireTracks(now, &fuse_events);
    for (const EyeEvent& e : fuse_events) Publish(e);
  }

  void Fuse(const FrameDetections& frame) {
    fuse_events.clear();
    try {
      const std::vector<LocalizedVehicle> cars = localizer.Fuse(frame, &fuse_events);
      for (const EyeEvent& e : fuse_events) Publish(e);
      if (!cars.empty()) PublishFleet(frame.stamp, cars);
    } catch (const std::exception& e) {
      // E.g. OpenCV refusing a degenerate registration: logged, the next frame goes on.
      spdlog::error("fusing a frame of camera {}: {}", frame.camera, e.what());
    }
  }

  void PublishFleet(Time stamp, const std::vector<LocalizedVehicle>& cars) {
    const EyeConfig& config = localizer.config();
    msg::FleetState& m = *fleet_message;
    m.header.stamp = dds::ToMsg(stamp);
    dds::UpdateString(m.header.frame_id, "map");
    dds::SetLengthKeepingCapacity(m.vehicles, static_cast<std::uint32_t>(cars.size()));
    for (std::size_t i = 0; i < cars.size(); ++i) {
      const LocalizedVehicle& car = cars[i];
      const VehicleTagConfig& v = config.vehicles[car.vehicle];
      const VehicleEstimate& e = car.estimate;
      auto& t = dds::Elements(m.vehicles)[i];
      dds::UpdateString(t.vehicle_id, v.name);
      t.tag_id = static_cast<std::uint32_t>(v.tag_id);
      t.source = autodrive_msgs_msg_TrackedVehicle_Constants_EYE;
      t.observed = dds::ToMsg(e.stamp);
      t.pose.pose = dds::ToMsg(
          RigidTransform2(Eigen::Vector2d(e.pose.x(), e.pose.y()), e.pose.z()).ToRigidTransform3());
      std::fill(std::begin(t.pose.covariance), std::end(t.pose.covariance), 0.0);
      // ROS order x, y, z, roll, pitch, yaw: (x, y, yaw) at indices 0, 1, 5.
      const int index[3] = {0, 1, 5};
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) t.pose.covariance[index[r] * 6 + index[c]] = e.covariance(r, c);
      }
      t.twist.twist = msg::Twist{};
      t.twist.twist.linear.x = e.speed_mps;
      t.twist.twist.angular.z = e.yaw_rate_radps;
      std::fill(std::begin(t.twist.covariance), std::end(t.twist.covariance), 0.0);
      t.twist.covariance[0] = e.covariance(3, 3);
      t.twist.covariance[35] = e.covariance(4, 4);
      t.twist.covariance[5] = t.twist.covariance[30] = e.covariance(3, 4);
      dds::UpdateString(t.map_lane_id, "");
      t.intersection_id = 0;
      t.approach_id = 0;
      t.distance_to_stop_line_m = 0.0;
      if (!ips_writers.empty()) {
        ips_writers[car.vehicle]->Write(msg::Point{e.pose.x(), e.pose.y(), 0.0});
      }
    }
    fleet_writer.Write(fleet_message);
    const double latency_ms = ToSeconds(SystemNow() - stamp) * 1e3;
    const std::lock_guard lock(counters_mutex);
    ++counters.fleet_messages;
    if (latencies_ms.size() < kLatencies) {
      latencies_ms.push_back(latency_ms);
    } else {
      latencies_ms[latency_next] = latency_ms;
      latency_next = (latency_next + 1) % kLatencies;
    }
  }
};

EyeService::EyeService(const EyeConfig& config, const dds::Participant& participant, EyeMode mode)
    : impl_(std::make_unique<Impl>(config, participant, mode)) {}

EyeService::~EyeService() = default;

void EyeService::Stop() { impl_->StopThreads(); }

void EyeService::Step(Time now) {
  AUTODRIVE_THROW_UNLESS(!impl_->stepped.empty() || impl_->threads.empty(),
                         "EyeService::Step: the service runs on threads, not in lockstep");
  impl_->Step(now);
}

bool EyeService::WaitForAcks(std::chrono::steady_clock::duration timeout) const {
  return impl_->WaitForAcks(timeout);
}

void EyeService::Reregister() {
  for (std::size_t c = 0; c < impl_->localizer.camera_count(); ++c) {
    impl_->localizer.Reregister(c);
  }
}

bool EyeService::finished() const {
  return impl_->files_running.load() == 0 &&
         std::all_of(impl_->localizer.config().cameras.begin(),
                     impl_->localizer.config().cameras.end(), [](const CameraConfig& c) {
                       return c.source.rfind("images:", 0) == 0 || c.source.rfind("video:", 0) == 0;
                     });
}

ServiceCounters EyeService::counters() const {
  const std::lock_guard lock(impl_->counters_mutex);
  ServiceCounters c = impl_->counters;
  std::vector<double> l = impl_->latencies_ms;
  if (!l.empty()) {
    std::sort(l.begin(), l.end());
    c.latency_p50_ms = l[l.size() / 2];
    c.latency_p99_ms = l[std::min(l.size() - 1, l.size() * 99 / 100)];
  }
  return c;
}

}  // namespace autodrive::eye
