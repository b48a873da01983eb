#pragma once
/// @file
/// The simulator as a DDS service (`autodrive-sim --city CONFIG`): every car of the city's
/// `sim` section speaks the AutoDRIVE devkit topics exactly as the real car does
/// (docs/messaging.md), plus its ground truth; the simulator publishes `/clock`; the lamp states
/// of the city's traffic lights (`signal_<i>/state`) are part of the world's state.
///
/// Each control period (10 ms by default) the service takes the newest command of every car
/// and the newest background traffic (`/autodrive/scm/traffic`, traffic.h: SUMO's vehicles
/// become boxes that the LIDARs see, the cameras draw and the cars collide with), advances
/// the physics by whole steps, publishes every sensor reading that fell due and
/// `/clock`, and in real-time mode sleeps until the wall clock catches up. In lockstep it
/// then waits until every reader acknowledged the step's messages, announces the step on
/// `/autodrive/sim/step` and waits for every configured controller's `step_done` before the
/// next period, so that the same seed and the same controllers give the same run. A car whose
/// command stream stops (no throttle or steering command for `command_timeout`) is held still
/// (throttle 0), as the real car's firmware does, until a command arrives again.
///
/// Districts (docs/districts.md): in a city with a `districts:` section, each car's `ips` (what
/// the SCMs' fleets read) goes also to the domain of the district the car is in, on that
/// district's participant, and the lamp states of each district's heads are read there; every
/// topic stays on the service's participant (the cars' own domain) as well.
///
/// Times: messages carry the simulated time as ROS time. In real time it starts at the wall
/// clock's time when the service starts, so that programs on the wall clock (the SCM, the
/// lights) and the simulator agree; in fast mode it starts at 0, as ROS simulators' /clock.

#include <atomic>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "common/dds/participant.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::vehicle_sim {

/// What a light shows: 0 off, 1 red, 2 yellow, 3 green (the devkit's values).
using LampState = std::int32_t;

/// A participant on each district's domain, in the order of the city's `districts:` section
/// (each must outlive the service; one may be the service's own participant). Empty for a city
/// without districts.
using DistrictParticipants = std::vector<const dds::Participant*>;

class SimService {
 public:
  /// Builds the world of `map` with the city's cars and their DDS endpoints on `participant`.
  /// @throws InputError (or ConfigError) for a bad configuration.
  SimService(const dds::Participant& participant, const SimCity& city, const maps::Map& map,
             const ServiceOptions& options, const DistrictParticipants& districts = {});
  ~SimService();
  SimService(const SimService&) = delete;
  SimService& operator=(const SimService&) = delete;

  /// Writes every car's ground truth after each control period to `out` (header first; CSV,
  /// `vehicle,` then `kReplayLogHeader`'s columns, 9 significant digits): the same run gives
  /// the same bytes. nullptr: no log. `out` must outlive `Run`.
  void LogTo(std::ostream* out);

  /// Runs until `stop` becomes true, the duration is reached, or a step fails (rethrown). In
  /// lockstep, first waits for every controller (see docs/vehicle_sim.md, "Lockstep").
  void Run(const std::atomic<bool>& stop);

  /// The lamp each signal head shows, as last reported on `signal_<i>/state` (absent: none
  /// heard yet).
  [[nodiscard]] std::map<SignalHeadId, LampState> Lamps() const;
  [[nodiscard]] Duration time() const;
  [[nodiscard]] std::int64_t steps() const;
  /// Times a car ran into a background object so far (a car and an object touching after
  /// not touching for a second or more; each is logged). Thread-safe.
  [[nodiscard]] std::int64_t traffic_collisions() const;
  /// Camera frames published so far, every camera together: a camera whose topic has no
  /// reader draws none. Thread-safe.
  [[nodiscard]] std::uint64_t camera_frames() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::vehicle_sim
