#include "vehicle_sim/replay.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <ostream>
#include <sstream>
#include <string>

#include "common/error.h"

namespace autodrive::vehicle_sim {

namespace {

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) {
    s.remove_suffix(1);
  }
  return s;
}

std::vector<std::string_view> SplitCommas(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    fields.push_back(Trim(line.substr(start, comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return fields;
}

// A whole field as a finite double, or nullopt.
std::optional<double> Number(std::string_view field) {
  if (field.empty()) return std::nullopt;
  const std::string text(field);
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v)) {
    return std::nullopt;
  }
  return v;
}

void Append(std::string& out, double v) {
  char buffer[32];
  const int n = std::snprintf(buffer, sizeof buffer, "%.9g", v == 0.0 ? 0.0 : v);  // no "-0"
  out.append(buffer, static_cast<std::size_t>(n));
}

}  // namespace

std::vector<TimedCommand> ParseCommandCsv(std::string_view text, std::string_view name) {
  std::vector<TimedCommand> commands;
  bool header_seen = false;
  int line_number = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t eol = text.find('\n', pos);
    const std::string_view line =
        Trim(text.substr(pos, eol == std::string_view::npos ? text.npos : eol - pos));
    pos = eol == std::string_view::npos ? text.size() + 1 : eol + 1;
    ++line_number;
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> fields = SplitCommas(line);
    if (!header_seen) {
      AUTODRIVE_THROW_UNLESS(fields.size() == 3 && fields[0] == "time_s" &&
                                 fields[1] == "throttle" && fields[2] == "steering",
                             name << ":" << line_number
                                  << ": expected the header 'time_s,throttle,steering', got '"
                                  << line << "'");
      header_seen = true;
      continue;
    }
    AUTODRIVE_THROW_UNLESS(fields.size() == 3, name << ":" << line_number
                                                    << ": expected 3 values (time_s,throttle,"
                                                       "steering), got "
                                                    << fields.size() << ": '" << line << "'");
    static constexpr const char* kNames[] = {"time_s", "throttle", "steering"};
    double values[3];
    for (std::size_t i = 0; i < 3; ++i) {
      const std::optional<double> v = Number(fields[i]);
      AUTODRIVE_THROW_UNLESS(v.has_value(), name << ":" << line_number << ": " << kNames[i]
                                                 << " is not a finite number: '" << fields[i]
                                                 << "'");
      values[i] = *v;
    }
    AUTODRIVE_THROW_UNLESS(
        values[0] >= 0, name << ":" << line_number << ": time_s " << fields[0] << " is negative");
    const Duration t = FromSeconds(values[0]);
    AUTODRIVE_THROW_UNLESS(commands.empty() || t >= commands.back().time,
                           name << ":" << line_number << ": time_s " << fields[0]
                                << " goes back (the previous row has "
                                << ToSeconds(commands.back().time) << ")");
    for (std::size_t i = 1; i < 3; ++i) {
      AUTODRIVE_THROW_UNLESS(std::abs(values[i]) <= 1.0, name << ":" << line_number << ": "
                                                              << kNames[i] << " " << fields[i]
                                                              << " is outside [-1, 1]");
    }
    commands.push_back({t, {values[1], values[2]}});
  }
  AUTODRIVE_THROW_UNLESS(header_seen, name << ": empty: expected the header "
                                              "'time_s,throttle,steering' and rows");
  AUTODRIVE_THROW_UNLESS(!commands.empty(), name << ": no commands after the header");
  return commands;
}

std::vector<TimedCommand> ReadCommandCsv(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  AUTODRIVE_THROW_UNLESS(in.good(), path.string() << ": cannot read the command file");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseCommandCsv(text.str(), path.string());
}

void WriteReplayRow(std::ostream& out, Duration time, const VehicleState& s) {
  std::string row;
  row.reserve(256);
  const auto add = [&](double v) {
    if (!row.empty()) row += ',';
    Append(row, v);
  };
  add(ToSeconds(time));
  add(s.X_MV.translation().x());
  add(s.X_MV.translation().y());
  add(s.X_MV.yaw());
  add(s.v_V_mps.x());
  add(s.v_V_mps.y());
  add(s.w_V_radps.z());
  for (const WheelState& w : s.wheels) add(w.spin_radps);
  add(s.wheels[0].steer_rad);
  add(s.wheels[1].steer_rad);
  row += ',' + std::to_string(s.encoder_ticks[0]) + ',' + std::to_string(s.encoder_ticks[1]);
  row += '\n';
  out << row;
}

void RunReplay(World& world, int vehicle, const std::vector<TimedCommand>& commands,
               const ReplayOptions& options, std::ostream& out,
               const std::function<void(Duration, Duration)>& progress) {
  AUTODRIVE_THROW_UNLESS(!commands.empty(), "no commands to replay");
  const Duration step = world.options().step;
  const std::int64_t log_every = std::max<std::int64_t>(1, options.log_period / step);
  const Duration start = world.time();
  const Duration total = commands.back().time + options.tail;
  out << kReplayLogHeader << '\n';
  WriteReplayRow(out, Duration{0}, world.State(vehicle));
  std::size_t next = 0;
  std::int64_t steps = 0;
  Duration reported{0};
  while (world.time() - start < total) {
    const Duration now = world.time() - start;
    while (next < commands.size() && commands[next].time <= now) {
      world.SetCommand(vehicle, commands[next].command);
      ++next;
    }
    world.Step();
    ++steps;
    if (steps % log_every == 0) WriteReplayRow(out, world.time() - start, world.State(vehicle));
    if (progress && world.time() - start - reported >= std::chrono::seconds(1)) {
      reported = world.time() - start;
      progress(reported, total);
    }
  }
  AUTODRIVE_THROW_UNLESS(out.good(), "writing the replay log failed");
}

}  // namespace autodrive::vehicle_sim
