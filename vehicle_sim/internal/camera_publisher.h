#pragma once
/// @file
/// The simulator service's cameras (service.cpp): the frames that fall due, rendered from the
/// world and published on each camera's image topic, in the loop's thread (lockstep and fast
/// mode: reproducible) or each camera on its own thread (real time: the physics loop does not
/// wait for them; a frame that falls due while the last is still being rendered is dropped and
/// counted).

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/writer.h"
#include "common/time.h"
#include "maps/map.h"
#include "vehicle_sim/cameras.h"
#include "vehicle_sim/renderer.h"
#include "vehicle_sim/sim_config.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim::internal {

class CameraWorker;

/// Every camera of a simulated city and its writer. Not copyable or movable (its writers and
/// workers are not). `PublishDue` and `WaitForAcks` for the loop's thread only; the workers
/// publish from their own.
class CameraPublisher {
 public:
  /// The cameras of `sim` for the cars already in `world` (SimCameras), a writer each on
  /// `participant` (which must outlive it); `threaded`: a worker thread per camera (real-time
  /// mode). Each frame's noise is drawn from `sim.seed`, the camera and the frame's time.
  /// @throws InputError or ConfigError (naming the camera) for a bad lens or tag.
  CameraPublisher(const dds::Participant& participant, const SimConfig& sim, const maps::Map& map,
                  const World& world, bool threaded);
  ~CameraPublisher();
  CameraPublisher(const CameraPublisher&) = delete;
  CameraPublisher& operator=(const CameraPublisher&) = delete;

  /// Renders and publishes the frames due at the world's time, stamped `stamp`. `fill(lights,
  /// lamps)` fills the cars' lights and the lamps lit (each vector reused), called only when a
  /// frame is due; `traffic`: the background objects as they look now.
  template <typename Fill>
  void PublishDue(const World& world, Time stamp, const std::vector<RenderTraffic>& traffic,
                  Fill&& fill) {
    if (!Due(world.time())) return;
    fill(lights_, head_lamps_);
    PublishFrames(world, stamp, traffic);
  }

  /// Waits until every reader of every camera acknowledged its frames (warns, naming the
  /// camera, when one did not within `timeout`).
  void WaitForAcks(std::chrono::steady_clock::duration timeout) const;

  [[nodiscard]] bool empty() const { return cameras_->empty(); }
  /// Frames published so far, every camera together (a camera with no reader draws none).
  /// Thread-safe.
  [[nodiscard]] std::uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }

 private:
  // Whether a frame is due at `now` (`due_`: which).
  bool Due(Duration now);
  void PublishFrames(const World& world, Time stamp, const std::vector<RenderTraffic>& traffic);
  // Publishes camera k's frame (from the loop's thread, or the camera's worker).
  void PublishImage(std::size_t k, const Image& image, Time stamp);

  std::unique_ptr<SimCameras> cameras_;
  std::vector<std::unique_ptr<dds::Writer<msg::Image>>> writers_;  // in `cameras_`' order
  std::uint64_t seed_;
  std::vector<std::size_t> due_;
  std::vector<CarLights> lights_;
  std::vector<HeadLamps> head_lamps_;
  Image image_;
  std::atomic<std::uint64_t> frames_{0};
  std::vector<std::unique_ptr<CameraWorker>> workers_;  // real-time mode: one per camera; last
};

}  // namespace autodrive::vehicle_sim::internal
