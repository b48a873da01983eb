#pragma once
/// @file
/// The co-simulation on DDS (`autodrive-traffic run`): reads the lamps every light reports
/// (`signal_<i>/state`) and the lab's cars (simulator ground truth, the Eye's fleet, or the
/// SCM's fleet state), steps `CoSimulation`, and publishes SUMO's vehicles as
/// `TrafficObjects` on `/autodrive/scm/traffic` after every step.
///
/// Time: SUMO's step k is due at the start instant plus k steps of the process's clock (the
/// wall clock, or the simulator's `/clock` with `--clock sim`); a SUMO slower than its clock
/// runs behind and says so. In lockstep (`--lockstep NAME`) it is a controller of the
/// simulator's lockstep (docs/vehicle_sim.md): at each step stamp it runs the SUMO steps that
/// fell due, publishes, waits until every reader has the objects, and answers; with the same
/// seed two runs then publish the same objects.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "traffic/cosim.h"
#include "traffic/traffic_config.h"

#include "common/dds/messages.h"
#include "common/dds/participant.h"
#include "common/time.h"

namespace autodrive::scm {
struct City;
}

namespace autodrive::traffic {

struct TrafficServiceOptions {
  std::filesystem::path work_dir;  ///< the network and SUMO's log
  /// Lockstep: the controller name to answer the simulator's steps with; empty: follow `clock`.
  std::string lockstep;
  Clock* clock = nullptr;  ///< follow mode: the process's clock (wall or /clock)
  /// Stop after this much SUMO time (0: never; lockstep also stops at the simulator's end).
  Duration duration{0};
  /// Every step's objects as CSV lines (`ObjectsCsvHeader`), e.g. for comparing runs.
  std::ostream* log = nullptr;
  /// A city of districts (docs/districts.md): a participant on each district's domain, in the
  /// order of the city's `districts:` section (each must outlive the service). Each district's
  /// lamps are read there, and its own vehicles (by `maps::Districts::At`) are published there
  /// as well; every vehicle still goes to the service's participant (the simulator's domain).
  std::vector<const dds::Participant*> districts;
};

/// `out` holding `vehicles` (strings and the sequence borrowed from `vehicles` and `buffer`,
/// which must outlive it), stamped `stamp`, frame "map".
void FillTrafficObjects(const std::vector<TrafficVehicle>& vehicles, Time stamp,
                        std::vector<msg::TrafficObject>& buffer, msg::TrafficObjects& out);

/// The CSV header of the objects log: `stamp_s,id,class,x_m,y_m,yaw_rad,speed_mps,length_m,
/// width_m,lane,signals`.
[[nodiscard]] const char* ObjectsCsvHeader();

class TrafficService {
 public:
  /// Starts SUMO (see CoSimulation) and creates the DDS entities. `city` and `participant`
  /// must outlive it.
  TrafficService(const dds::Participant& participant, const scm::City& city,
                 const TrafficConfig& config, TrafficServiceOptions options);
  ~TrafficService();
  TrafficService(const TrafficService&) = delete;
  TrafficService& operator=(const TrafficService&) = delete;

  /// Runs until `stop`, the duration, or (lockstep) the simulator's last step.
  void Run(const std::atomic<bool>& stop);

  [[nodiscard]] const CoSimulation& cosim() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::traffic
