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

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "city/dashboard/hub.h"
#include "city/dashboard/internal/feed_converter.h"
#include "city/dashboard/internal/feed_streams.h"
#include "city/dashboard/internal/shown_devices.h"

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

/// One participant's streams, read and handed to the hub as they arrive: the lamps, events,
/// the device table, V2I request status and the Eye's fleet by listeners on Cyclone's threads;
/// SPaT, the fleet and the traffic by its converter thread (internal::FeedConverter). Not
/// copyable or movable (the listeners hold `this`).
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
  /// The lamps' readers: each counts its samples and hands them to the hub.
  [[nodiscard]] std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> ListenToLamps(
      const dds::Participant& participant, const std::vector<SignalHeadId>& heads);

  // Made in this order (the readers' listeners use what is above them) and taken down in the
  // reverse, the converter's thread stopped first (~Feed).
  Hub& hub_;
  const std::string district_;
  internal::FeedCounters counters_;
  internal::ShownDevices devices_shown_;
  std::vector<std::unique_ptr<dds::Reader<msg::Int32>>> heads_;
  internal::FeedConverter converter_;  ///< SPaT, the fleet and the traffic (its own readers)
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
