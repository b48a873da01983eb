#pragma once
/// @file
/// Everything the SCM runs for one city, built whole off the loop and swapped in whole: the
/// city's runtime (controllers, monitors), device supervision, the lights' command writers, the
/// fleet registry and its sources, and the MAP and signs messages. A failed build leaves the
/// running city untouched.

#include <memory>
#include <string>
#include <vector>

#include "common/dds/participant.h"
#include "scm/core/city.h"
#include "scm/core/device_table.h"
#include "scm/core/fleet.h"
#include "scm/core/runtime.h"
#include "scm/core/supervision.h"
#include "scm/io/fleet_sources.h"
#include "scm/io/publishers.h"
#include "scm/store/store.h"

namespace autodrive::scm {

/// One city, ready to run. Members are destroyed in reverse order: the parts that borrow the
/// city go before it. Not copyable or movable.
class CityBundle {
 public:
  /// Builds everything for `city`: its readers in `participant`, its lights' writers from
  /// `writers` (shared with the city it replaces). `restore`: the operator states to start the
  /// intersections with. `clock`: the kind the daemon runs on (how positions are stamped, see
  /// `IpsSource`). Slow for a big city.
  CityBundle(std::unique_ptr<City> city, const dds::Participant& participant, ClockKind clock,
             SignalCommandWriters& writers, std::vector<IntersectionStateRecord> restore,
             std::uint32_t map_revision);
  CityBundle(const CityBundle&) = delete;
  CityBundle& operator=(const CityBundle&) = delete;
  ~CityBundle();

  /// Starts the controllers at `now` (the start-up sequence) with `restore`'s modes, plans and
  /// phase controls, and forgets what devices said
  /// (a new session of the control timeline, or a newly applied city).
  void Start(const ClockReading& now);

  [[nodiscard]] const City& city() const { return runtime->city(); }

  std::vector<IntersectionStateRecord> restore;
  std::unique_ptr<CityRuntime> runtime;
  std::unique_ptr<DeviceSupervisor> supervisor;
  std::unique_ptr<DeviceTable> devices;  ///< what the supervisor took, for the device table
  std::unique_ptr<LightCommander> lights;
  std::unique_ptr<FleetRegistry> fleet;
  std::vector<std::unique_ptr<ObservationSource>> sources;
  MapMessages map;
};

/// The supervision parameters of a city.
[[nodiscard]] SupervisionParams SupervisionParamsOf(const City& city);

}  // namespace autodrive::scm
