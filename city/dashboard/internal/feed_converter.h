#pragma once
/// @file
/// A dashboard feed's converter thread: SPaT, the SCM's fleet and SUMO's traffic each repeat
/// their whole state, so their listeners (on Cyclone's threads) only note that a sample waits,
/// and this thread takes the latest (history 1), converts it to the page's JSON and hands it to
/// the hub. Cyclone's receive thread stays free to drain its socket, and a converter that falls
/// behind skips samples (the next replaces the last) instead of queueing them.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <unordered_map>

#include "city/dashboard/hub.h"
#include "city/dashboard/internal/feed_streams.h"

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"

namespace autodrive::dashboard::internal {

/// The readers of SPaT, the fleet and the traffic, and the thread that converts what they
/// take. Thread contract: the readers' listeners and the thread share the flags under
/// `mutex_`; the samples, the revisions and the traffic's time are the thread's alone. Not
/// copyable or movable (the listeners hold `this`).
class FeedConverter {
 public:
  /// Subscribes on `participant` to SPaT and the SCM's fleet (`scm_streams`) and to SUMO's
  /// traffic (`city_streams`). What it converts goes to `hub`, the fleet as district
  /// `district`'s (empty: a city without districts) and each vehicle with it; it counts each
  /// sample taken in `counters`. `participant`, `hub` and `counters` must outlive it. Nothing
  /// is converted before `Start`.
  FeedConverter(const dds::Participant& participant, bool scm_streams, bool city_streams,
                std::string district, Hub& hub, FeedCounters& counters);
  FeedConverter(const FeedConverter&) = delete;
  FeedConverter& operator=(const FeedConverter&) = delete;
  /// Stops the thread, then closes the readers (traffic, fleet, SPaT).
  ~FeedConverter();

  /// Starts the thread (once).
  void Start();
  /// Stops the thread and waits for it. The listeners may still note samples after it; nothing
  /// takes them. Idempotent.
  void Stop();

 private:
  /// SUMO's traffic is converted at most this often (Hub::Options::traffic_interval).
  static constexpr std::chrono::milliseconds kTrafficInterval{95};

  /// The thread: takes and converts SPaT, the fleet and the traffic when their listeners note
  /// a sample, the latest only.
  void Convert();
  void ConvertWaiting(bool do_spat, bool do_fleet, bool do_traffic);

  Hub& hub_;
  const std::string district_;
  FeedCounters& counters_;
  std::mutex mutex_;  ///< guards the flags below
  std::condition_variable cv_;
  bool spat_waiting_ = true, fleet_waiting_ = true, traffic_waiting_ = true, stop_ = false;
  std::chrono::steady_clock::time_point traffic_converted_{};
  std::unordered_map<std::uint32_t, std::uint32_t> spat_revisions_;  ///< the thread's
  dds::Message<msg::Spat> spat_sample_;                              ///< the thread's, reused
  dds::Message<msg::FleetState> fleet_sample_;
  dds::Message<msg::TrafficObjects> traffic_sample_;
  std::atomic<std::uint64_t> errors_{0};
  // After what their listeners use; closed before it goes.
  std::unique_ptr<dds::Reader<msg::Spat>> spat_reader_;
  std::unique_ptr<dds::Reader<msg::FleetState>> fleet_reader_;
  std::unique_ptr<dds::Reader<msg::TrafficObjects>> traffic_reader_;
  std::thread thread_;  ///< joined before anything above goes
};

}  // namespace autodrive::dashboard::internal
