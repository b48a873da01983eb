#pragma once
/// @file
/// Replaying a recorded command sequence on one simulated car, headless and without DDS: how a
/// lab checks the model against its own car (`autodrive-sim replay`).
///
/// Commands: a CSV file with the header `time_s,throttle,steering` and one row per command
/// (seconds from the start, non-decreasing; throttle and steering normalised to [-1, 1] as on
/// the devkit topics). Each command holds from its time until the next one's. Blank lines and
/// lines starting with `#` are skipped.
///
/// Log: a CSV file with one row per logged step, header `kReplayLogHeader`: the car's ground
/// truth (the vehicle frame V: middle of the rear axle; map frame), velocities in V, wheel
/// speeds, front wheel steering angles and rear encoder ticks. Numbers are printed with 9
/// significant digits, so the same run gives the same bytes.

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string_view>
#include <vector>

#include "common/time.h"
#include "vehicle_sim/vehicle.h"
#include "vehicle_sim/world.h"

namespace autodrive::vehicle_sim {

/// One row of a command file.
struct TimedCommand {
  Duration time{0};
  VehicleCommand command;
  bool operator==(const TimedCommand&) const = default;
};

/// Reads a command file. @throws InputError naming the file, the line and the value for a
/// missing or wrong header, a row without exactly three numbers, a non-finite or decreasing
/// time, or a throttle or steering outside [-1, 1]; and for an empty file (no rows).
[[nodiscard]] std::vector<TimedCommand> ReadCommandCsv(const std::filesystem::path& path);
/// The same from text; `name` stands for the file in messages.
[[nodiscard]] std::vector<TimedCommand> ParseCommandCsv(std::string_view text,
                                                        std::string_view name);

inline constexpr std::string_view kReplayLogHeader =
    "time_s,x_m,y_m,yaw_rad,v_x_mps,v_y_mps,yaw_rate_radps,"
    "wheel_fl_radps,wheel_fr_radps,wheel_rl_radps,wheel_rr_radps,"
    "steer_left_rad,steer_right_rad,ticks_left,ticks_right";

/// Writes one log row (no header) for `state` at `time`.
void WriteReplayRow(std::ostream& out, Duration time, const VehicleState& state);

struct ReplayOptions {
  /// Log every this often (rounded to whole physics steps; at least one step).
  Duration log_period = std::chrono::milliseconds(10);
  /// Keep running this long after the last command (which holds).
  Duration tail = Duration{0};
};

/// Runs `commands` on vehicle `vehicle` of `world` from its current time, writing the header
/// and a row at the start and every log period to `out`. `progress(done, total)` (simulated
/// time) is called about every simulated second when given.
void RunReplay(World& world, int vehicle, const std::vector<TimedCommand>& commands,
               const ReplayOptions& options, std::ostream& out,
               const std::function<void(Duration, Duration)>& progress = {});

}  // namespace autodrive::vehicle_sim
