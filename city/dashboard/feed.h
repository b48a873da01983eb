#pragma once
/// @file
/// What the dashboard reads from DDS, handed to the `Hub` as it arrives (no polling: listeners
/// on Cyclone's threads, and a converter thread they wake for SPaT, the fleet and traffic): each
/// head's `signal_<i>/state`, SPaT, the SCM's fleet, SUMO's traffic, events, device status, V2I
/// request status, and the Eye's fleet (for its rate). JSON shapes in docs/dashboard.md.
///
/// One `Feed` reads one participant. A city of districts (docs/districts.md) is read by one on
/// the dashboard's own domain (SUMO's traffic, the Eye) and one on each district's domain (its
/// SCM's streams and the lamps of its intersections' heads): `CityFeed` and `DistrictFeed` say
/// which streams each takes.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "city/dashboard/hub.h"

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/dds/reader.h"
#include "maps/districts.h"
#include "maps/map.h"
#include "scm/core/city.h"

namespace autodrive::dashboard {

/// Messages received per stream since the start (for the rates in `stats`).
struct FeedCounts {
  std::uint64_t lamps = 0;
  std::uint64_t spat = 0;
  std::uint64_t fleet = 0;
  std::uint64_t traffic = 0;
  std::uint64_t eye = 0;
  std::uint64_t events = 0;
  std::uint64_t devices = 0;
};

/// Which streams a `Feed` reads on its participant.
struct FeedOptions {
  /// The district whose domain the participant is on: the page's objects of its SCM's streams
  /// (vehicles, events, devices, requests) carry it as "district", and its fleet is its own
  /// source in the hub. Empty for a city without districts (no "district" fields).
  std::string district;
  /// The heads whose lamps (`signal_<i>/state`) it reads.
  std::vector<SignalHeadId> heads;
  /// The SCM's streams: SPaT, its fleet, events, the device table and V2I request status.
  bool scm_streams = true;
  /// The whole city's streams: SUMO's traffic and the Eye's fleet.
  bool city_streams = true;
};

/// What the dashboard reads on its own domain: for a city without districts (`districts` empty)
/// every stream and every head of `map`; with districts only SUMO's traffic (it publishes every
/// vehicle there) and the Eye's fleet, as each district's SCM and lamps are on its domain.
[[nodiscard]] FeedOptions CityFeed(const maps::Map& map, const maps::Districts& districts);
/// What the dashboard reads on district `district`'s domain: its SCM's streams and the lamps of
/// the heads of its intersections.
[[nodiscard]] FeedOptions DistrictFeed(const maps::Map& map, const maps::District& district);

class Feed {
 public:
  /// Subscribes on `participant` (which, like `hub`, must outlive it) to the streams `options`
  /// names.
  Feed(const dds::Participant& participant, FeedOptions options, Hub& hub);
  /// Subscribes to the heads of `map` and every stream (a city without districts).
  Feed(const dds::Participant& participant, const maps::Map& map, Hub& hub)
      : Feed(participant, CityFeed(map, maps::Districts{}), hub) {}
  Feed(const Feed&) = delete;
  Feed& operator=(const Feed&) = delete;
  ~Feed();

  [[nodiscard]] FeedCounts counts() const;

 private:
  /// SUMO's traffic is converted at most this often (Hub::Options::traffic_interval).
  static constexpr std::chrono::milliseconds kTrafficInterval{95};

  /// The converter thread: takes and converts SPaT, the fleet and the traffic when their
  /// listeners note a sample, the latest only.
  void Convert();
  void ConvertWaiting(bool do_spat, bool do_fleet, bool do_traffic);

  /// The page's object of this feed's SCM's stream: `object` with "district" when there is one.
  [[nodiscard]] nlohmann::json InDistrict(nlohmann::json object) const;

  Hub& hub_;
  const std::string district_;
  std::mutex convert_mutex_;  ///< guards the flags below
  std::condition_variable convert_cv_;
  bool spat_waiting_ = true, fleet_waiting_ = true, traffic_waiting_ = true, stop_ = false;
  std::chrono::steady_clock::time_point traffic_converted_{};
  std::unordered_map<std::uint32_t, std::uint32_t> spat_revisions_;  ///< the converter's
  dds::Message<msg::Spat> spat_sample_;                              ///< the converter's, reused
  dds::Message<msg::FleetState> fleet_sample_;
  dds::Message<msg::TrafficObjects> traffic_sample_;
  std::atomic<std::uint64_t> convert_errors_{0};
  std::thread converter_;
  std::mutex devices_mutex_;  ///< guards devices_shown_ (listeners may run on several threads)
  /// What the page shows of a device, as last sent.
  struct DeviceShown {
    std::uint8_t kind = 0, backend = 0, health = 0, mode = 0;
    bool reported = false, lost = false;
    std::string host, detail;
  };
  struct TextHash {
    using is_transparent = void;
    std::size_t operator()(std::string_view s) const { return std::hash<std::string_view>{}(s); }
  };
  std::unordered_map<std::string, DeviceShown, TextHash, std::equal_to<>> devices_shown_;
  std::atomic<std::uint64_t> lamps_{0}, spat_{0}, fleet_{0}, traffic_{0}, eye_{0}, events_{0},
      devices_{0};
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> heads_;
  std::unique_ptr<dds::Reader<msg::Spat>> spat_reader_;
  std::unique_ptr<dds::Reader<msg::FleetState>> fleet_reader_;
  std::unique_ptr<dds::Reader<msg::TrafficObjects>> traffic_reader_;
  std::unique_ptr<dds::Reader<msg::Event>> events_reader_;
  std::unique_ptr<dds::Reader<msg::DeviceTable>> devices_reader_;
  std::unique_ptr<dds::Reader<msg::SignalRequestStatus>> requests_reader_;
  std::unique_ptr<dds::Reader<msg::FleetState>> eye_reader_;
};

// --- Conversions (docs/dashboard.md's objects), public for tests ------------------------------
[[nodiscard]] nlohmann::json SpatIntersectionJson(const msg::IntersectionState& x);
[[nodiscard]] nlohmann::json VehicleJson(const msg::TrackedVehicle& v);
[[nodiscard]] nlohmann::json TrafficObjectJson(const msg::TrafficObject& o);
[[nodiscard]] nlohmann::json EventJson(const msg::Event& e);
/// The page's event (E) of a value of the SCM's `events` answer (its typed fields,
/// docs/scm.md): the same object `EventJson` makes of the same event on the wire.
[[nodiscard]] nlohmann::json HistoryEventJson(const nlohmann::json& event);
/// The page's intersection (I) of a value (an object) of the SCM's `intersections` answer,
/// named `name`.
[[nodiscard]] nlohmann::json IntersectionJson(const std::string& name, nlohmann::json x);
[[nodiscard]] nlohmann::json DeviceJson(const msg::DeviceEntry& d);
[[nodiscard]] nlohmann::json RequestJson(const msg::SignalRequestStatus& r);
/// The names of the IntersectionState status bits set in `status` ("failure_flash", ...).
[[nodiscard]] nlohmann::json StatusFlags(std::uint16_t status);
/// The static map object M of docs/dashboard.md, with the city's signal groups (and, in a city
/// of districts, its districts and each intersection's); `px_per_tile`, `margin_px` and the size
/// as the map's SVG was drawn.
[[nodiscard]] nlohmann::json MapJson(const scm::City& city, double px_per_tile, int margin_px,
                                     int width_px, int height_px);

}  // namespace autodrive::dashboard
