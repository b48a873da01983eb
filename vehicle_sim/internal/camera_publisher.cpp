#include "vehicle_sim/internal/camera_publisher.h"

#include <spdlog/spdlog.h>

#include <condition_variable>
#include <functional>
#include <mutex>
#include <span>
#include <thread>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"

namespace autodrive::vehicle_sim::internal {

// Renders one camera's frames on its own thread (real-time mode), so that the physics loop does
// not wait for them: a frame that falls due while the last one is still being rendered is
// dropped and counted.
class CameraWorker {
 public:
  using Publish = std::function<void(const Image&, Time)>;
  CameraWorker(SimCameras& cameras, std::size_t k, Publish publish)
      : cameras_(cameras), k_(k), publish_(std::move(publish)), thread_([this] { Loop(); }) {}
  ~CameraWorker() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  CameraWorker(const CameraWorker&) = delete;
  CameraWorker& operator=(const CameraWorker&) = delete;

  // Hands over the camera's frame from the cameras' last snapshot; false (dropped) when busy.
  bool Offer(std::uint64_t noise_seed, Time stamp) {
    std::lock_guard lock(mutex_);
    if (busy_) {
      ++dropped_;
      return false;
    }
    cameras_.MakeJob(k_, noise_seed, job_);
    stamp_ = stamp;
    busy_ = true;
    wake_.notify_one();
    return true;
  }
  std::int64_t dropped() const {
    std::lock_guard lock(mutex_);
    return dropped_;
  }

 private:
  void Loop() {
    std::unique_lock lock(mutex_);
    while (true) {
      wake_.wait(lock, [this] { return stop_ || busy_; });
      if (stop_) return;
      lock.unlock();
      cameras_.Render(k_, job_, image_);
      publish_(image_, stamp_);
      lock.lock();
      busy_ = false;
    }
  }

  SimCameras& cameras_;
  std::size_t k_;
  Publish publish_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool busy_ = false;  // a job is waiting or being rendered (job_ and stamp_ are the worker's)
  bool stop_ = false;
  std::int64_t dropped_ = 0;
  SimCameras::Job job_;
  Time stamp_;
  Image image_;
  std::thread thread_;  // last: started when everything above is ready
};

namespace {

void SetHeader(std_msgs_msg_dds__Header_& header, Time stamp, const char* frame) {
  header.stamp = dds::ToMsg(stamp);
  dds::BorrowString(header.frame_id, frame);
}

}  // namespace

CameraPublisher::CameraPublisher(const dds::Participant& participant, const SimConfig& sim,
                                 const maps::Map& map, const World& world, bool threaded)
    : cameras_(std::make_unique<SimCameras>(sim, map, world)), seed_(sim.seed) {
  namespace topics = dds::topics;
  for (const SimCamera& cam : cameras_->cameras()) {
    writers_.push_back(std::make_unique<dds::Writer<msg::Image>>(
        participant, !cam.vehicle_id ? topics::OverheadCamera(cam.name)
                     : cam.front     ? topics::FrontCamera(*cam.vehicle_id)
                                     : topics::RearCamera(*cam.vehicle_id)));
    spdlog::info("camera {}: {} x {} at {:.3g} Hz", cam.name, cam.intrinsics.width_px,
                 cam.intrinsics.height_px, 1.0 / ToSeconds(cam.period));
  }
  if (threaded) {
    for (std::size_t k = 0; k < writers_.size(); ++k) {
      workers_.push_back(std::make_unique<CameraWorker>(
          *cameras_, k, [this, k](const Image& im, Time stamp) { PublishImage(k, im, stamp); }));
    }
  }
}

CameraPublisher::~CameraPublisher() = default;

bool CameraPublisher::Due(Duration now) {
  if (cameras_->empty()) return false;
  cameras_->Due(now, due_);
  // A camera nobody reads is not drawn (drawing is most of the simulator's work: an overhead
  // camera the Eye does not use, in a run without it). Each frame's noise depends only on the
  // seed, the camera and the time, so the frames drawn are the same whichever were skipped.
  std::erase_if(due_, [this](std::size_t k) { return writers_[k]->matched_readers() == 0; });
  return !due_.empty();
}

void CameraPublisher::PublishFrames(const World& world, Time stamp,
                                    const std::vector<RenderTraffic>& traffic) {
  cameras_->Snapshot(world, lights_, head_lamps_, traffic);
  for (const std::size_t k : due_) {
    // Each frame's noise from the seed, the camera and the frame's time.
    const auto stamp_ns = static_cast<std::uint64_t>(world.time().count());
    const std::uint64_t noise =
        seed_ * 0x9e3779b97f4a7c15ULL ^ (k + 1) * 0xbf58476d1ce4e5b9ULL ^ stamp_ns;
    if (!workers_.empty()) {
      if (!workers_[k]->Offer(noise, stamp) && workers_[k]->dropped() % 100 == 1) {
        spdlog::warn("camera {}: {} frame(s) dropped: rendering is slower than the frame rate",
                     cameras_->cameras()[k].name, workers_[k]->dropped());
      }
      continue;
    }
    cameras_->Render(k, image_, noise);
    PublishImage(k, image_, stamp);
  }
}

void CameraPublisher::PublishImage(std::size_t k, const Image& im, Time stamp) {
  const SimCamera& cam = cameras_->cameras()[k];
  msg::Image m{};
  SetHeader(m.header, stamp, cam.frame_id.c_str());
  m.width = static_cast<std::uint32_t>(im.width_px);
  m.height = static_cast<std::uint32_t>(im.height_px);
  dds::BorrowString(m.encoding, "rgb8");
  m.is_bigendian = 0;
  m.step = 3 * m.width;
  auto& data = const_cast<std::vector<std::uint8_t>&>(im.rgb);
  dds::BorrowSequence(m.data, std::span<std::uint8_t>(data));
  writers_[k]->Write(m);
  frames_.fetch_add(1, std::memory_order_relaxed);
}

void CameraPublisher::WaitForAcks(std::chrono::steady_clock::duration timeout) const {
  for (std::size_t k = 0; k < writers_.size(); ++k) {
    if (!writers_[k]->WaitForAcks(timeout)) {
      spdlog::warn("camera {}: a reader did not acknowledge its frame in time",
                   cameras_->cameras()[k].name);
    }
  }
}

}  // namespace autodrive::vehicle_sim::internal
