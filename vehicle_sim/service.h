#pragma once
/// @file
/// The simulator as a DDS service (`autodrive-sim --city CONFIG`): every car of the city's
/// `sim` section speaks the AutoDRIVE devkit topics exactly as the real car does
/// (docs/messaging.md), plus its ground truth; the simulator publishes `/clock`; the lamp states
/// of the city's traffic lights (`signal_<i>/state`) are part of the world's state.
///
/// Each control period (10 ms by default) the service takes the newest command of every car,
/// advances the physics by whole steps, publishes every sensor reading that fell due and
/// `/clock`, and in real-time mode sleeps until the wall clock catches up. A car whose command
/// stream stops (no throttle or steering command for `command_timeout`) is held still (throttle
/// 0), as the real car's firmware does, until a command arrives again.
///
/// Times: messages carry the simulated time as ROS time. In real time it starts at the wall
/// clock's time when the service starts, so that programs on the wall clock (the SCM, the
/// lights) and the simulator agree; in fast mode it starts at 0, as ROS simulators' /clock.

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>

#include "common/dds/participant.h"
#include "common/ids.h"
#include "common/time.h"
#include "maps/map.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::vehicle_sim {

enum class SimMode {
  kRealTime,  ///< paced by the wall clock (times real_time_factor)
  kFast,      ///< as fast as the machine goes
};
constexpr auto ConfigEnumNames(SimMode) {
  return std::array{std::pair{SimMode::kRealTime, std::string_view{"realtime"}},
                    std::pair{SimMode::kFast, std::string_view{"fast"}}};
}

struct ServiceOptions {
  SimMode mode = SimMode::kRealTime;
  double real_time_factor = 1.0;  ///< simulated seconds per wall second in real-time mode
  Duration control_period = std::chrono::milliseconds(10);
  Duration command_timeout = std::chrono::milliseconds(500);
  std::optional<Duration> duration;  ///< stop after this much simulated time
};

/// What a light shows: 0 off, 1 red, 2 yellow, 3 green (the devkit's values).
using LampState = std::int32_t;

class SimService {
 public:
  /// Builds the world of `map` with the city's cars and their DDS endpoints on `participant`.
  /// @throws InputError (or ConfigError) for a bad configuration.
  SimService(const dds::Participant& participant, const SimCity& city, const maps::Map& map,
             const ServiceOptions& options);
  ~SimService();
  SimService(const SimService&) = delete;
  SimService& operator=(const SimService&) = delete;

  /// Runs until `stop` becomes true, the duration is reached, or a step fails (rethrown).
  void Run(const std::atomic<bool>& stop);

  /// The lamp each signal head shows, as last reported on `signal_<i>/state` (absent: none
  /// heard yet).
  [[nodiscard]] std::map<SignalHeadId, LampState> Lamps() const;
  [[nodiscard]] Duration time() const;
  [[nodiscard]] std::int64_t steps() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::vehicle_sim
