#pragma once
/// @file
/// The Eye online: each camera's frames read on a thread of its own (a simulated overhead
/// camera's image topic, or a device, stream or files) and searched there, one thread fusing
/// them in the localiser, and the fleet published on DDS: `/autodrive/eye/fleet` (source EYE,
/// pose and twist with covariances), the devkit's `ips` per car when configured, and events.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>

#include "common/dds/participant.h"
#include "common/time.h"
#include "eye/eye_config.h"

namespace autodrive::eye {

/// Counters of a running service.
struct ServiceCounters {
  std::uint64_t frames = 0;             ///< frames searched, all cameras
  std::uint64_t fleet_messages = 0;     ///< fleet messages published
  std::uint64_t dropped_frames = 0;     ///< frames skipped because the camera's last was busy
  std::uint64_t bad_frames = 0;         ///< frames refused (wrong size or encoding)
  std::uint64_t unreadable_frames = 0;  ///< frames of files or devices that did not decode
  double latency_p50_ms = 0.0;          ///< exposure stamp to fleet message written, wall clock
  double latency_p99_ms = 0.0;
};

/// How the service runs.
enum class EyeMode {
  kThreads,   ///< each camera on its own thread, as frames come (the lab, a real-time twin)
  kLockstep,  ///< no threads: `Step` searches and fuses what came, on the simulator's steps
};

/// The service. Starts its threads on construction and stops them on destruction (or `Stop`).
/// Not copyable or movable.
///
/// In lockstep (`EyeMode::kLockstep`, the simulator's lockstep: common/dds/lockstep.h) the
/// cameras must be simulated ones (`topic:`): at each step the caller calls `Step` with the
/// step's time, which takes every frame each camera's topic brought (the simulator waited
/// for their acknowledgements before it announced the step), searches them one after the
/// other, fuses them in stamp order and publishes, then `WaitForAcks`; a camera is lost after
/// 2 s of simulated time without a frame. The same frames give the same fleet every run.
class EyeService {
 public:
  /// @throws ConfigError / InputError for a bad configuration or calibration file,
  /// InputError when a source cannot be opened (or, in lockstep, is not a `topic:` camera).
  EyeService(const EyeConfig& config, const dds::Participant& participant,
             EyeMode mode = EyeMode::kThreads);
  ~EyeService();
  EyeService(const EyeService&) = delete;
  EyeService& operator=(const EyeService&) = delete;

  /// Stops the threads (idempotent).
  void Stop();
  /// Lockstep only: searches and fuses the frames that came, publishes, judges the cameras'
  /// silence at `now` (the step's simulated time).
  void Step(Time now);
  /// Lockstep only: whether every reader acknowledged what `Step` wrote, within `timeout`.
  [[nodiscard]] bool WaitForAcks(std::chrono::steady_clock::duration timeout) const;
  /// Every camera registers again from its next frames (`Localizer::Reregister`).
  void Reregister();
  /// True once every file source has ended (a service on files only is then done).
  [[nodiscard]] bool finished() const;
  [[nodiscard]] ServiceCounters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::eye
