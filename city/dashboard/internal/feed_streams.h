#pragma once
/// @file
/// What the parts of a dashboard `Feed` (city/dashboard/feed.h) share: the counts of the
/// messages they receive, how a stream that repeats its whole state is read, a sample's times,
/// and the page's objects of a district's SCM.

#include <atomic>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/qos.h"
#include "common/dds/reader.h"
#include "common/dds/topic_spec.h"
#include "common/time.h"

namespace autodrive::dashboard::internal {

/// Messages received per stream since the start (`FeedCounts`, as the feed's listeners on
/// Cyclone's threads and its converter thread add to them). Thread-safe.
struct FeedCounters {
  std::atomic<std::uint64_t> lamps{0};
  std::atomic<std::uint64_t> spat{0};
  std::atomic<std::uint64_t> fleet{0};
  std::atomic<std::uint64_t> traffic{0};
  std::atomic<std::uint64_t> eye{0};
  std::atomic<std::uint64_t> events{0};
  std::atomic<std::uint64_t> devices{0};
};

/// The same topic read best-effort and volatile: for the streams that repeat their whole state
/// (SPaT at 10 Hz, SUMO's traffic at 20 Hz, the fleets, each light's periodic status), where
/// the next sample makes up for a lost one (none is lost on one host). Writers send such a
/// reader no heartbeats and wait for no acknowledgement from it. Acknowledging the lights'
/// statuses (5,120 a second in a 32x32 city) was 18% of the dashboard's CPU (Cyclone's
/// timed-event thread, 16x16 grid: 1% after). The lamps (`signal_<i>/state`, sent only on a
/// change) stay reliable.
template <typename T>
dds::TopicSpec<T> Repeating(dds::TopicSpec<T> spec) {
  spec.qos.reliability = dds::Qos::Reliability::kBestEffort;
  spec.qos.durability = dds::Qos::Durability::kVolatile;
  return spec;
}

/// `t` in seconds (of its own clock's epoch).
inline double Seconds(const msg::Time& t) { return ToSeconds(dds::FromMsg(t)); }

/// The sample's source timestamp, in milliseconds.
inline double SourceMs(const dds::SampleInfo& info) {
  return static_cast<double>(info.source_timestamp_ns) / 1e6;
}

/// The page's object of the SCM's stream of district `district`: `object` with "district"
/// when there is one (`district` not empty).
inline nlohmann::json InDistrict(const std::string& district, nlohmann::json object) {
  if (!district.empty()) object["district"] = district;
  return object;
}

}  // namespace autodrive::dashboard::internal
