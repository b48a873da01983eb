#pragma once
/// @file
/// The project's QoS profiles: the only place QoS is decided (see docs/messaging.md).
///
/// Every profile uses XCDR1 data representation, like ROS 2, and reliable delivery so that
/// ROS 2 subscribers with default QoS (reliable) match our writers.

#include <dds/dds.h>

#include <cstdint>
#include <memory>
#include <string>

#include "common/time.h"

namespace autodrive::dds {

/// A QoS profile for a topic's readers and writers. Value type.
struct Qos {
  enum class Reliability { kBestEffort, kReliable };
  enum class Durability { kVolatile, kTransientLocal };

  Reliability reliability = Reliability::kReliable;
  Durability durability = Durability::kVolatile;
  /// History depth (keep last N); 0 means keep all.
  std::int32_t depth = 1;
  /// How long a reliable writer may block when a reader's history is full (keep-all only).
  Duration max_blocking = std::chrono::milliseconds(100);
  /// Readers only, with a reliable profile: best-effort writers (a ROS 2 node's
  /// `SensorDataQoS` publisher) are read too, through a best-effort companion reader beside
  /// the reliable one (common/dds/reader.h). Reliable writers still deliver reliably, once, to
  /// the reliable reader. Writers ignore it.
  bool reader_accepts_best_effort = false;

  /// Periodic data where only the newest sample matters: sensors, SPaT, fleet state, /clock.
  /// Reliable, volatile, keep last `depth`.
  static Qos Stream(std::int32_t depth = 1);
  /// State that late joiners must get at once (ROS's "latched"): MAP, signs, configuration,
  /// device status. Reliable, transient-local, keep last `depth` per writer.
  static Qos LatchedState(std::int32_t depth = 1);
  /// Commands and requests where every sample matters: operator requests and replies, V2I
  /// requests. Reliable, volatile, keep all: a burst is never thinned; a reader that does not
  /// keep up makes the writer block for at most `max_blocking`, then the write fails.
  static Qos Command();
  /// Data a ROS 2 node may publish to us (a car's devkit topics: its sensors and the actuator
  /// commands): `Stream` whose readers accept best-effort writers too
  /// (`reader_accepts_best_effort`), so ROS's default and `SensorDataQoS` publishers match.
  static Qos RosInput(std::int32_t depth = 1);
  /// Best-effort sensor stream (ROS's SensorDataQoS), for high-rate data where a lost sample
  /// is better than a late one. Only ROS subscribers that are best-effort too will match.
  static Qos BestEffortStream(std::int32_t depth = 5);

  /// The same profile for a writer on a loop that must never block: `max_blocking` 0, so a
  /// write that would wait for slow readers' acknowledgements fails at once (the caller counts
  /// it and retries or drops). Readers are unaffected (they ignore `max_blocking`).
  [[nodiscard]] Qos NonBlocking() const {
    Qos q = *this;
    q.max_blocking = Duration{0};
    return q;
  }

  bool operator==(const Qos&) const = default;
  /// "reliable/transient_local/keep_last(1)" style text.
  [[nodiscard]] std::string ToString() const;
};

namespace internal {
/// Owner of a `dds_qos_t`.
struct QosDeleter {
  void operator()(dds_qos_t* q) const { dds_delete_qos(q); }
};
using QosPtr = std::unique_ptr<dds_qos_t, QosDeleter>;
/// The Cyclone QoS object for a profile.
QosPtr MakeQos(const Qos& qos);
/// Publisher/subscriber QoS with one partition (none when `partition` is empty).
QosPtr MakePartitionQos(const std::string& partition);
}  // namespace internal

}  // namespace autodrive::dds
