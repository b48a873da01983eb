#include "city/dashboard/internal/feed_converter.h"

#include <spdlog/spdlog.h>

#include <exception>
#include <utility>
#include <vector>

#include "city/dashboard/feed.h"

#include "common/dds/topics.h"

namespace autodrive::dashboard::internal {

using nlohmann::json;

FeedConverter::FeedConverter(const dds::Participant& participant, bool scm_streams,
                             bool city_streams, std::string district, Hub& hub,
                             FeedCounters& counters)
    : hub_(hub), district_(std::move(district)), counters_(counters) {
  const auto note = [this](bool FeedConverter::*waiting) {
    {
      std::lock_guard lock(mutex_);
      this->*waiting = true;
    }
    cv_.notify_one();
  };
  if (scm_streams) {
    spat_reader_ =
        std::make_unique<dds::Reader<msg::Spat>>(participant, Repeating(dds::topics::Spat()));
    fleet_reader_ = std::make_unique<dds::Reader<msg::FleetState>>(participant,
                                                                   Repeating(dds::topics::Fleet()));
    spat_reader_->OnDataAvailable(
        [note](dds::Reader<msg::Spat>&) { note(&FeedConverter::spat_waiting_); });
    fleet_reader_->OnDataAvailable(
        [note](dds::Reader<msg::FleetState>&) { note(&FeedConverter::fleet_waiting_); });
  }
  if (city_streams) {
    traffic_reader_ = std::make_unique<dds::Reader<msg::TrafficObjects>>(
        participant, Repeating(dds::topics::Traffic()));
    traffic_reader_->OnDataAvailable(
        [note](dds::Reader<msg::TrafficObjects>&) { note(&FeedConverter::traffic_waiting_); });
  }
}

FeedConverter::~FeedConverter() {
  // The thread first (it takes from the readers), then the readers: their listeners use this
  // object.
  Stop();
  traffic_reader_.reset();
  fleet_reader_.reset();
  spat_reader_.reset();
}

void FeedConverter::Start() {
  thread_ = std::thread([this] { Convert(); });
}

void FeedConverter::Stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void FeedConverter::Convert() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    // SUMO's traffic comes at 20 Hz and the page draws at most 10: a sample that comes sooner
    // is left in the reader, where the next replaces it, never converted from CDR at all (and
    // the one converted is always converted as it comes, fresh).
    const auto now = std::chrono::steady_clock::now();
    const bool traffic_due = traffic_waiting_ && now - traffic_converted_ >= kTrafficInterval;
    if (!traffic_due) traffic_waiting_ = false;
    if (!spat_waiting_ && !fleet_waiting_ && !traffic_due) {
      cv_.wait(lock);
      continue;
    }
    const bool do_spat = std::exchange(spat_waiting_, false);
    const bool do_fleet = std::exchange(fleet_waiting_, false);
    if (traffic_due) {
      traffic_waiting_ = false;
      traffic_converted_ = now;
    }
    lock.unlock();
    try {
      ConvertWaiting(do_spat, do_fleet, traffic_due);
    } catch (const std::exception& e) {
      // As a listener's would be: logged and counted, never fatal (bad text from the network
      // makes JSON throw). The next sample is converted as usual.
      const std::uint64_t n = ++errors_;
      if (n <= 5 || n % 100 == 0) {
        spdlog::error("dashboard: converting a sample failed ({} so far): {}", n, e.what());
      }
    }
    lock.lock();
  }
}

void FeedConverter::ConvertWaiting(bool do_spat, bool do_fleet, bool do_traffic) {
  dds::SampleInfo info;
  if (do_spat && spat_reader_) {
    while (spat_reader_->TakeOne(spat_sample_, &info)) {
      counters_.spat.fetch_add(1);
      // JSON only for the intersections whose revision changed: a big city's SPaT is mostly
      // the same from one message to the next.
      std::vector<json> xs;
      for (const auto& x : dds::Elements(spat_sample_->intersections)) {
        const auto [it, added] = spat_revisions_.try_emplace(x.intersection_id, x.revision);
        if (!added && it->second == x.revision) continue;
        it->second = x.revision;
        xs.push_back(SpatIntersectionJson(x));
      }
      hub_.SetSpat(Seconds(spat_sample_->header.stamp), std::move(xs), SourceMs(info));
    }
  }
  if (do_fleet && fleet_reader_) {
    while (fleet_reader_->TakeOne(fleet_sample_, &info)) {
      counters_.fleet.fetch_add(1);
      json vs = json::array();
      for (const auto& v : dds::Elements(fleet_sample_->vehicles)) {
        vs.push_back(InDistrict(district_, VehicleJson(v)));
      }
      hub_.SetFleet(district_, Seconds(fleet_sample_->header.stamp), std::move(vs), SourceMs(info));
    }
  }
  if (do_traffic && traffic_reader_) {
    while (traffic_reader_->TakeOne(traffic_sample_, &info)) {
      counters_.traffic.fetch_add(1);
      json os = json::array();
      for (const auto& o : dds::Elements(traffic_sample_->objects))
        os.push_back(TrafficObjectJson(o));
      hub_.SetTraffic(std::move(os), SourceMs(info));
    }
  }
}

}  // namespace autodrive::dashboard::internal
