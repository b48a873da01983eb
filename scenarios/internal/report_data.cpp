#include "scenarios/internal/report_data.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <string>

#include "scenarios/internal/logs.h"
#include "scenarios/metrics.h"

#include "common/dds/messages.h"
#include "common/error.h"

namespace autodrive::scenarios::internal {

namespace {

namespace fs = std::filesystem;
using Eigen::Vector2d;
using nlohmann::json;

// Millimetres and milliseconds: what a chart can show, and a page a fifth the size.
double Mm(double x) { return std::round(x * 1000.0) / 1000.0; }
json Json(const std::optional<double>& x) { return x ? json(Mm(*x)) : json(nullptr); }

// The list `key` of a car's metrics (empty when it has none or it is not a list).
const json& ListOf(const json& metrics, const char* key) {
  static const json empty = json::array();
  const auto it = metrics.find(key);
  return it != metrics.end() && it->is_array() ? *it : empty;
}

// ---- The logs ----

// A log the run writes: missing is noted (the page says so), not an error.
std::optional<std::ifstream> OpenLog(const fs::path& file, json& notes) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    notes.push_back(fmt::format("{}: missing", file.filename().string()));
    return std::nullopt;
  }
  return in;
}

// Calls f(fields, line number) for each row after the header with at least `columns` fields.
template <typename F>
void ForEachCsvRow(const fs::path& file, std::size_t columns, json& notes, F f) {
  auto in = OpenLog(file, notes);
  if (!in) return;
  std::string line;
  std::getline(*in, line);  // header
  for (std::size_t n = 2; std::getline(*in, line); ++n) {
    if (line.empty()) continue;
    const auto fields = SplitCsv(line);
    if (fields.size() < columns) {
      throw InputError(
          fmt::format("{}:{}: {} fields, expected {}", file.string(), n, fields.size(), columns));
    }
    f(fields, n);
  }
}

std::vector<json> ReadJsonl(const fs::path& file, json& notes) {
  std::vector<json> out;
  auto in = OpenLog(file, notes);
  if (!in) return out;
  std::string line;
  for (std::size_t n = 1; std::getline(*in, line); ++n) {
    if (line.empty()) continue;
    try {
      json j = json::parse(line);
      if (!j.is_object() || !j.contains("t_s") || !j["t_s"].is_number()) {
        throw InputError(fmt::format("{}:{}: not an object with a number t_s", file.string(), n));
      }
      out.push_back(std::move(j));
    } catch (const json::exception& e) {
      throw InputError(fmt::format("{}:{}: {}", file.string(), n, e.what()));
    }
  }
  return out;
}

struct Sample {
  double t = 0, x = 0, y = 0, yaw = 0, v = 0;
};

Vector2d Ahead(const Sample& s, double ahead_m) {
  return Vector2d(s.x, s.y) + ahead_m * Vector2d(std::cos(s.yaw), std::sin(s.yaw));
}

// The sample at or just before t (the first one before the track starts).
const Sample& At(const std::vector<Sample>& track, double t) {
  auto it = std::upper_bound(track.begin(), track.end(), t + 1e-9,
                             [](double x, const Sample& s) { return x < s.t; });
  return it == track.begin() ? track.front() : *(it - 1);
}

double SegmentDistance(const Vector2d& p, const Vector2d& a, const Vector2d& b) {
  const Vector2d d = b - a;
  const double n2 = d.squaredNorm();
  const double t = n2 > 0 ? std::clamp((p - a).dot(d) / n2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

json Xy(const Points& points) {
  json x = json::array(), y = json::array();
  for (const Vector2d& p : points) {
    x.push_back(Mm(p.x()));
    y.push_back(Mm(p.y()));
  }
  return {{"x", std::move(x)}, {"y", std::move(y)}};
}

// ---- Names of the wire numbers (the IDL's constants) ----

std::string Named(const std::map<int, std::string>& names, int value) {
  const auto it = names.find(value);
  return it == names.end() ? std::to_string(value) : it->second;
}

const std::map<int, std::string>& SeverityNames() {
  static const std::map<int, std::string> names{
      {autodrive_msgs_msg_Event_Constants_DEBUG, "debug"},
      {autodrive_msgs_msg_Event_Constants_INFO, "info"},
      {autodrive_msgs_msg_Event_Constants_WARNING, "warning"},
      {autodrive_msgs_msg_Event_Constants_ALARM, "alarm"},
      {autodrive_msgs_msg_Event_Constants_CRITICAL, "critical"}};
  return names;
}

const std::map<int, std::string>& RequestTypeNames() {
  static const std::map<int, std::string> names{
      {autodrive_msgs_msg_SignalRequest_Constants_PRIORITY, "priority"},
      {autodrive_msgs_msg_SignalRequest_Constants_PREEMPTION, "preemption"},
      {autodrive_msgs_msg_SignalRequest_Constants_UPDATE, "update"},
      {autodrive_msgs_msg_SignalRequest_Constants_CANCEL, "cancel"}};
  return names;
}

const std::map<int, std::string>& RequestStatusNames() {
  static const std::map<int, std::string> names{
      {autodrive_msgs_msg_SignalRequestStatus_Constants_RECEIVED, "received"},
      {autodrive_msgs_msg_SignalRequestStatus_Constants_PROCESSING, "processing"},
      {autodrive_msgs_msg_SignalRequestStatus_Constants_GRANTED, "granted"},
      {autodrive_msgs_msg_SignalRequestStatus_Constants_REJECTED, "rejected"},
      {autodrive_msgs_msg_SignalRequestStatus_Constants_COMPLETED, "completed"},
      {autodrive_msgs_msg_SignalRequestStatus_Constants_CANCELLED, "cancelled"}};
  return names;
}

// The J2735 IntersectionStatusObject bits set in `status`, by name (as the dashboard names them).
std::vector<std::string> StatusFlags(int status) {
  static const std::pair<int, const char*> kFlags[] = {
      {autodrive_msgs_msg_IntersectionState_Constants_MANUAL_CONTROL_ENABLED, "manual_control"},
      {autodrive_msgs_msg_IntersectionState_Constants_STOP_TIME_ACTIVATED, "stop_time"},
      {autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH, "failure_flash"},
      {autodrive_msgs_msg_IntersectionState_Constants_PREEMPT_ACTIVE, "preempt"},
      {autodrive_msgs_msg_IntersectionState_Constants_SIGNAL_PRIORITY_ACTIVE, "priority"},
      {autodrive_msgs_msg_IntersectionState_Constants_FIXED_TIME_OPERATION, "fixed_time"},
      {autodrive_msgs_msg_IntersectionState_Constants_TRAFFIC_DEPENDENT_OPERATION, "actuated"},
      {autodrive_msgs_msg_IntersectionState_Constants_STANDBY_OPERATION, "standby"},
      {autodrive_msgs_msg_IntersectionState_Constants_FAILURE_MODE, "failure"},
      {autodrive_msgs_msg_IntersectionState_Constants_OFF, "off"},
      {autodrive_msgs_msg_IntersectionState_Constants_NO_VALID_MAP_AVAILABLE, "no_map"},
      {autodrive_msgs_msg_IntersectionState_Constants_NO_VALID_SPAT_AVAILABLE, "no_spat"}};
  std::vector<std::string> out;
  for (const auto& [bit, name] : kFlags) {
    if ((status & bit) != 0) out.emplace_back(name);
  }
  return out;
}

std::string Str(const json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}
double Num(const json& j, const char* key, double otherwise = 0) {
  const auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : otherwise;
}

// ---- Pieces of the page's data ----

// When the car's front first crossed the line going its way (within its ends).
std::optional<double> FrontCrossing(const RunWorld::StopLine& line, const RunWorld::Car& car,
                                    const std::vector<Sample>& track) {
  const Vector2d mid = (line.left + line.right) / 2;
  const double half = (line.left - line.right).norm() / 2;
  const Vector2d across(-line.direction.y(), line.direction.x());
  const double ahead = car.centre_ahead_m + car.length_m / 2;
  for (std::size_t i = 1; i < track.size(); ++i) {
    const double before = (Ahead(track[i - 1], ahead) - mid).dot(line.direction);
    const Vector2d p = Ahead(track[i], ahead) - mid;
    if (before < 0 && p.dot(line.direction) >= 0 && std::abs(p.dot(across)) <= half + 0.02) {
      return track[i].t;
    }
  }
  return std::nullopt;
}

// The stop lines a car meets, in order: those on its route (a line whose middle is on a
// segment of the route going its way), or, without a route, those its front crossed.
std::vector<std::size_t> LinesOfCar(const RunWorld& world, const RunWorld::Car& car,
                                    const std::vector<Sample>& track) {
  std::vector<std::pair<double, std::size_t>> found;
  for (std::size_t l = 0; l < world.stop_lines.size(); ++l) {
    const RunWorld::StopLine& line = world.stop_lines[l];
    if (car.route.empty()) {
      if (const auto t = FrontCrossing(line, car, track)) found.emplace_back(*t, l);
      continue;
    }
    const Vector2d mid = (line.left + line.right) / 2;
    double along = 0;
    for (std::size_t i = 0; i + 1 < car.route.size(); ++i) {
      const Vector2d d = car.route[i + 1] - car.route[i];
      if (d.norm() > 0 && d.normalized().dot(line.direction) > 0.5 &&
          SegmentDistance(mid, car.route[i], car.route[i + 1]) <= 0.05) {
        found.emplace_back(along, l);
        break;
      }
      along += d.norm();
    }
  }
  std::sort(found.begin(), found.end());
  std::vector<std::size_t> out;
  for (const auto& [at, l] : found) out.push_back(l);
  return out;
}

json Track(const std::vector<Sample>& track) {
  json t = json::array(), x = json::array(), y = json::array(), yaw = json::array(),
       v = json::array();
  const std::size_t stride = (track.size() + kMaxTrackSamples - 1) / kMaxTrackSamples;
  for (std::size_t i = 0; i < track.size(); i += std::max<std::size_t>(stride, 1)) {
    // The last sample always: the track ends where the car stood at the end.
    const Sample& s = i + stride >= track.size() ? track.back() : track[i];
    t.push_back(Mm(s.t));
    x.push_back(Mm(s.x));
    y.push_back(Mm(s.y));
    yaw.push_back(Mm(s.yaw));
    v.push_back(Mm(s.v));
  }
  return {{"t", t}, {"x", x}, {"y", y}, {"yaw", yaw}, {"v", v}};
}

std::string Fixed(const json& j, const char* key, int decimals) {
  return j.contains(key) && j[key].is_number()
             ? fmt::format("{:.{}f}", j[key].get<double>(), decimals)
             : std::string("?");
}

// Each infraction of the car (and its goal), with where it happened: the point of the body the
// metric measures (docs/scenarios.md, "Metrics"): the tail crossing a red light's stop line, the
// front crossing a stop sign's or reaching the goal, the body's centre for a collision (the
// contact's side is not logged) and a lane departure.
json CarMarks(const RunWorld::Car& car, const json& metrics, const std::vector<Sample>& track) {
  json marks = json::array();
  const double front = car.centre_ahead_m + car.length_m / 2;
  const double tail = car.centre_ahead_m - car.length_m / 2;
  const auto add = [&](double t, const std::string& kind, double ahead_m,
                       const std::string& label) {
    json m{{"t", Mm(t)}, {"kind", kind}, {"label", label}};
    if (!track.empty()) {
      const Vector2d p = Ahead(At(track, t), ahead_m);
      m["x"] = Mm(p.x());
      m["y"] = Mm(p.y());
    }
    marks.push_back(std::move(m));
  };
  if (!metrics.is_object()) return marks;
  for (const json& c : ListOf(metrics, "collisions")) {
    add(Num(c, "t_s"), "collision", car.centre_ahead_m,
        fmt::format("collision with {} ({}) at {} m/s", Str(c, "with"), Str(c, "kind"),
                    Fixed(c, "speed_mps", 3)));
  }
  for (const json& r : ListOf(metrics, "red_light_violations")) {
    add(Num(r, "t_s"), "red_light", tail,
        fmt::format("red light run: head {} of {} from {} at {} m/s",
                    r.value("head", json()).dump(), Str(r, "intersection"), Str(r, "lane"),
                    Fixed(r, "speed_mps", 3)));
  }
  for (const json& r : ListOf(metrics, "stop_sign_violations")) {
    add(Num(r, "t_s"), "stop_sign", front,
        fmt::format("stop sign rolled at {} from {} (slowest {} m/s)", Str(r, "intersection"),
                    Str(r, "lane"), Fixed(r, "min_speed_mps", 3)));
  }
  for (const json& d : ListOf(metrics, "lane_departures")) {
    add(Num(d, "t_s"), "lane_departure", car.centre_ahead_m,
        fmt::format("lane departure for {} s, up to {} m outside", Fixed(d, "duration_s", 2),
                    Fixed(d, "max_offset_m", 3)));
  }
  if (metrics.contains("time_to_goal_s") && metrics["time_to_goal_s"].is_number()) {
    add(metrics["time_to_goal_s"].get<double>(), "goal", front, "goal reached");
  }
  std::stable_sort(marks.begin(), marks.end(),
                   [](const json& a, const json& b) { return a["t"] < b["t"]; });
  return marks;
}

json WorldData(const RunWorld& world) {
  json lanes = json::array();
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  const auto grow = [&](const Points& points) {
    for (const Vector2d& p : points) {
      x0 = std::min(x0, p.x());
      y0 = std::min(y0, p.y());
      x1 = std::max(x1, p.x());
      y1 = std::max(y1, p.y());
    }
  };
  for (const RunWorld::Lane& l : world.lanes) {
    json lane = Xy(l.centreline);
    lane["name"] = l.name;
    lane["width_m"] = Mm(l.width_m);
    lanes.push_back(std::move(lane));
    for (const Vector2d& p : l.centreline) {
      const Vector2d half(l.width_m / 2, l.width_m / 2);
      grow({p - half, p + half});
    }
  }
  json statics = json::array();
  for (const RunWorld::Static& s : world.statics) {
    json shape = Xy(s.footprint);
    shape["kind"] = s.kind;
    shape["name"] = s.name;
    shape["timed"] = s.from_s > 0 || s.until_s.has_value();
    statics.push_back(std::move(shape));
    // The map's outer walls are its frame: they bound the picture, as the lanes do.
    grow(s.footprint);
  }
  json lines = json::array();
  for (const RunWorld::StopLine& s : world.stop_lines) {
    grow({s.left, s.right});
    json line = Xy({s.left, s.right});
    line["lane"] = s.lane;
    line["intersection"] = s.intersection;
    line["control"] = s.control;
    line["heads"] = s.heads;
    lines.push_back(std::move(line));
  }
  json bounds = x0 <= x1 ? json{Mm(x0), Mm(y0), Mm(x1), Mm(y1)} : json(nullptr);
  return {{"lanes", lanes}, {"statics", statics}, {"stop_lines", lines}, {"bounds", bounds}};
}

// The time line: rows in the order they are drawn, marks {t, row, kind, label, detail, level}.
class Timeline {
 public:
  void Add(const std::string& row, double t, const std::string& kind, const std::string& label,
           const std::string& detail = "", const std::string& level = "") {
    auto it = std::find(rows_.begin(), rows_.end(), row);
    if (it == rows_.end()) it = rows_.insert(rows_.end(), row);
    marks_.push_back({{"t", Mm(t)},
                      {"row", static_cast<int>(it - rows_.begin())},
                      {"kind", kind},
                      {"label", label},
                      {"detail", detail},
                      {"level", level}});
  }
  void Row(const std::string& row) {
    if (std::find(rows_.begin(), rows_.end(), row) == rows_.end()) rows_.push_back(row);
  }
  [[nodiscard]] json ToJson() const { return {{"rows", rows_}, {"marks", marks_}}; }

 private:
  std::vector<std::string> rows_;
  json marks_ = json::array();
};

void ScenarioEvents(const std::vector<json>& events, Timeline& timeline) {
  if (events.empty()) return;
  timeline.Row("scenario");
  for (const json& e : events) {
    const std::string action = Str(e, "action");
    std::string label = action;
    if (action == "mode" || action == "plan") {
      label = fmt::format("{} {} → {}", action, Str(e, "intersection"), Str(e, action.c_str()));
    } else if (action == "lamp") {
      label = fmt::format("lamp {} of head {} {}", Str(e, "lamp"), Num(e, "head"), Str(e, "fault"));
    } else if (action == "unplug" || action == "plug") {
      label = fmt::format("{} head {}", action, Num(e, "head"));
    } else if (action == "link_cut" || action == "link_restore") {
      label = fmt::format("{} {}", action, Str(e, "host"));
    } else if (action == "place" || action == "remove") {
      label = fmt::format("{} obstacle {}", action, Str(e, "obstacle"));
    } else if (action == "camera_lost" || action == "camera_back") {
      label = fmt::format("{} {}", action, Str(e, "camera"));
    } else if (action == "surge") {
      label =
          fmt::format("surge of {} {} from {}", Num(e, "count"), Str(e, "type"), Str(e, "from"));
    } else {
      label = fmt::format("{} {} at {}", action, Str(e, "vehicle"), Str(e, "intersection"));
    }
    timeline.Add(
        "scenario", Num(e, "t_s"), "scenario", label,
        fmt::format("scenario event due at {} s, applied at {} s", Num(e, "at_s"), Num(e, "t_s")));
  }
}

void SpatChanges(const std::vector<json>& spat, std::map<int, std::string>& names,
                 Timeline& timeline) {
  std::map<int, std::pair<std::string, int>> last;  // intersection: plan, status
  for (const json& m : spat) {
    const int x = static_cast<int>(Num(m, "intersection"));
    const std::string name = Str(m, "name").empty() ? std::to_string(x) : Str(m, "name");
    names[x] = name;
    const std::string plan = Str(m, "plan");
    const int status = static_cast<int>(Num(m, "status"));
    const auto it = last.find(x);
    if (it != last.end() && it->second == std::pair{plan, status}) continue;
    std::string label;
    if (it == last.end() || it->second.first != plan) label = "plan " + plan;
    const std::vector<std::string> now = StatusFlags(status);
    const std::vector<std::string> before =
        it == last.end() ? std::vector<std::string>{} : StatusFlags(it->second.second);
    for (const std::string& f : now) {
      if (std::find(before.begin(), before.end(), f) == before.end()) {
        label += (label.empty() ? "+" : " +") + f;
      }
    }
    for (const std::string& f : before) {
      if (std::find(now.begin(), now.end(), f) == now.end()) {
        label += (label.empty() ? "−" : " −") + f;
      }
    }
    std::string flags;
    for (const std::string& f : now) flags += (flags.empty() ? "" : ", ") + f;
    const bool bad = (status & (autodrive_msgs_msg_IntersectionState_Constants_FAILURE_FLASH |
                                autodrive_msgs_msg_IntersectionState_Constants_FAILURE_MODE)) != 0;
    timeline.Add("SPaT " + name, Num(m, "t_s"), "spat", label,
                 fmt::format("SPaT of {}: plan {}, status {} ({})", name, plan, status,
                             flags.empty() ? "no flag" : flags),
                 bad ? "alarm" : "");
    last[x] = {plan, status};
  }
}

void ScmEvents(const std::vector<json>& events, const std::map<int, std::string>& names,
               Timeline& timeline) {
  for (const json& e : events) {
    const int x = static_cast<int>(Num(e, "intersection"));
    std::string where = x == 0 ? "" : Named(names, x);
    if (!Str(e, "device").empty()) where += (where.empty() ? "" : ", ") + Str(e, "device");
    // An alarm (warning or worse) raised or cleared; other events are never active.
    const int severity = static_cast<int>(Num(e, "severity"));
    const bool cleared = severity >= autodrive_msgs_msg_Event_Constants_WARNING &&
                         e.contains("active") && e["active"] == false;
    const std::string level = Named(SeverityNames(), severity);
    timeline.Add("SCM events", Num(e, "t_s"), "event",
                 Str(e, "code") + (cleared ? " (cleared)" : ""),
                 fmt::format("{} {} from {}{}: {}", level, Str(e, "code"), Str(e, "source"),
                             where.empty() ? "" : " (" + where + ")", Str(e, "message")),
                 level);
  }
}

void Requests(const std::vector<json>& lines, const std::map<int, std::string>& names,
              Timeline& timeline) {
  for (const json& r : lines) {
    const std::string vehicle = Str(r, "vehicle");
    const auto id = static_cast<long long>(Num(r, "request_id"));
    const std::string x = Named(names, static_cast<int>(Num(r, "intersection")));
    if (Str(r, "kind") == "request") {
      const std::string type = Named(RequestTypeNames(), static_cast<int>(Num(r, "type")));
      timeline.Add("V2I " + vehicle, Num(r, "t_s"), "request", fmt::format("#{} {}", id, type),
                   fmt::format("{} asks {} for {} (request {}, lane {} to {})", vehicle, x, type,
                               id, Num(r, "in_lane"), Num(r, "out_lane")));
    } else {
      const std::string status = Named(RequestStatusNames(), static_cast<int>(Num(r, "status")));
      std::string detail = fmt::format("{} answers {}'s request {}: {}", x, vehicle, id, status);
      if (!Str(r, "reason").empty()) detail += " (" + Str(r, "reason") + ")";
      if (r.contains("expected_green_s")) {
        detail += fmt::format(", green expected at {:.2f} s", Num(r, "expected_green_s"));
      }
      timeline.Add("V2I " + vehicle, Num(r, "t_s"), "status", fmt::format("#{} {}", id, status),
                   detail, status);
    }
  }
}

std::optional<RunWorld> ReadWorld(const fs::path& file, json& notes) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    notes.push_back("world.json: missing (no map)");
    return std::nullopt;
  }
  try {
    return RunWorld::FromJson(json::parse(in));
  } catch (const json::exception& e) {
    throw InputError(fmt::format("{}: {}", file.string(), e.what()));
  }
}

// Each car's ground truth, in time order.
std::map<std::string, std::vector<Sample>> ReadTracks(const fs::path& file, json& notes) {
  std::map<std::string, std::vector<Sample>> tracks;
  ForEachCsvRow(file, 6, notes, [&](const std::vector<std::string>& f, std::size_t n) {
    tracks[f[1]].push_back({Number(f[0], file, n), Number(f[2], file, n), Number(f[3], file, n),
                            Number(f[4], file, n), Number(f[5], file, n)});
  });
  return tracks;
}

json CarData(const RunWorld::Car& car, const json& metrics, const std::vector<Sample>& track,
             const RunWorld* world) {
  json lines = json::array();
  if (world != nullptr) {
    for (const std::size_t l : LinesOfCar(*world, car, track)) {
      const RunWorld::StopLine& line = world->stop_lines[l];
      lines.push_back({{"lane", line.lane},
                       {"intersection", line.intersection},
                       {"control", line.control},
                       {"heads", line.heads},
                       {"t_cross", Json(FrontCrossing(line, car, track))}});
    }
  }
  return {{"name", car.name},
          {"length_m", car.length_m},
          {"width_m", car.width_m},
          {"centre_ahead_m", car.centre_ahead_m},
          {"track", Track(track)},
          {"route", Xy(car.route)},
          {"marks", CarMarks(car, metrics, track)},
          {"stop_lines", std::move(lines)}};
}

// Each head's lamp as bands: {"<head>": {"bands": [[from_s, to_s, aspect], ...]}}.
json HeadsData(const fs::path& file, double end_s, json& notes) {
  std::map<int, std::vector<std::pair<double, int>>> lamps;
  ForEachCsvRow(file, 3, notes, [&](const std::vector<std::string>& f, std::size_t n) {
    lamps[static_cast<int>(Number(f[1], file, n))].emplace_back(
        Number(f[0], file, n), static_cast<int>(Number(f[2], file, n)));
  });
  json heads = json::object();
  for (const auto& [head, changes] : lamps) {
    json bands = json::array();
    for (const LampBand& b : LampBands(changes, std::max(end_s, changes.back().first))) {
      bands.push_back({Mm(b.from_s), Mm(b.to_s), b.aspect});
    }
    heads[std::to_string(head)] = {{"bands", std::move(bands)}};
  }
  return heads;
}

// A car's row of the time line: its infractions, its goal, the stop lines it crossed.
void CarRow(const json& car, Timeline& timeline) {
  static const std::map<std::string, std::string> kShort{{"collision", "collision"},
                                                         {"red_light", "red light"},
                                                         {"stop_sign", "stop sign"},
                                                         {"lane_departure", "lane departure"},
                                                         {"goal", "goal"}};
  const std::string name = car["name"].get<std::string>();
  timeline.Row(name);
  for (const json& m : car["marks"]) {
    const std::string kind = m["kind"].get<std::string>();
    timeline.Add(name, m["t"].get<double>(), kind, kShort.at(kind), m["label"].get<std::string>(),
                 kind == "goal" ? "" : "alarm");
  }
  for (const json& l : car["stop_lines"]) {
    if (l["t_cross"].is_null()) continue;
    timeline.Add(name, l["t_cross"].get<double>(), "stop_line", "stop line",
                 fmt::format("{}'s front crosses the {} line of {} ({})", name,
                             l["control"].get<std::string>(), l["intersection"].get<std::string>(),
                             l["lane"].get<std::string>()));
  }
}

}  // namespace

json ReportPageData(const json& report, const fs::path& run_dir) {
  const fs::path logs = run_dir / "logs";
  json notes = json::array();
  const double end_s =
      report.contains("end") && report["end"].is_object() ? Num(report["end"], "t_s") : 0.0;
  const std::optional<RunWorld> world = ReadWorld(logs / "world.json", notes);
  const auto tracks = ReadTracks(logs / "ground_truth.csv", notes);
  json heads = HeadsData(logs / "lamps.csv", end_s, notes);

  json cars = json::array();
  const json no_metrics = json::object();
  const json& vehicles = report.contains("metrics") && report["metrics"].contains("vehicles")
                             ? report["metrics"]["vehicles"]
                             : no_metrics;
  std::vector<RunWorld::Car> known;
  if (world) {
    known = world->cars;
  } else {
    for (const auto& [name, v] : vehicles.items()) {
      known.emplace_back();
      known.back().name = name;
    }
  }
  for (const RunWorld::Car& car : known) {
    const auto track = tracks.find(car.name);
    cars.push_back(CarData(car, vehicles.contains(car.name) ? vehicles[car.name] : no_metrics,
                           track == tracks.end() ? std::vector<Sample>{} : track->second,
                           world ? &*world : nullptr));
  }

  Timeline timeline;
  std::map<int, std::string> names;
  ScenarioEvents(ReadJsonl(logs / "scenario_events.jsonl", notes), timeline);
  SpatChanges(ReadJsonl(logs / "spat.jsonl", notes), names, timeline);
  ScmEvents(ReadJsonl(logs / "events.jsonl", notes), names, timeline);
  Requests(ReadJsonl(logs / "requests.jsonl", notes), names, timeline);
  for (const json& car : cars) CarRow(car, timeline);
  json intersections = json::object();
  for (const auto& [id, name] : names) intersections[std::to_string(id)] = name;

  return {{"report", report},
          {"end_s", end_s},
          {"world", world ? WorldData(*world) : json(nullptr)},
          {"cars", std::move(cars)},
          {"heads", std::move(heads)},
          {"timeline", timeline.ToJson()},
          {"intersections", std::move(intersections)},
          {"notes", std::move(notes)}};
}

json SummaryPageData(const json& summary) {
  if (!summary.is_object() || !summary.contains("variants") || !summary["variants"].is_array()) {
    throw InputError("summary: not an object with a list of variants");
  }
  json data = summary;
  std::vector<std::string> metrics;
  if (summary.contains("metrics") && summary["metrics"].is_array()) {
    for (const json& m : summary["metrics"]) {
      if (m.is_string()) metrics.push_back(m.get<std::string>());
    }
  }
  const bool listed = !metrics.empty();
  for (json& variant : data["variants"]) {
    if (!variant.is_object() || !variant.contains("runs") || !variant["runs"].is_array()) {
      throw InputError(fmt::format("summary: variant {} has no list of runs",
                                   variant.is_object() ? variant.value("name", "?") : "?"));
    }
    for (json& run : variant["runs"]) {
      if (!run.is_object()) continue;
      const std::string report = Str(run, "report");
      if (!report.empty()) {
        fs::path html(report);
        html.replace_extension(".html");
        run["html"] = html.generic_string();
      }
      if (!listed && run.contains("metrics") && run["metrics"].is_object()) {
        for (const auto& [name, value] : run["metrics"].items()) {
          if (std::find(metrics.begin(), metrics.end(), name) == metrics.end()) {
            metrics.push_back(name);
          }
        }
      }
    }
  }
  data["metrics"] = metrics;
  for (json& variant : data["variants"]) {
    if (!variant.contains("stats") || !variant["stats"].is_object())
      variant["stats"] = json::object();
    for (const std::string& m : metrics) {
      if (variant["stats"].contains(m)) continue;
      std::vector<double> values;
      for (const json& run : variant["runs"]) {
        if (run.is_object() && run.contains("metrics") && run["metrics"].contains(m) &&
            run["metrics"][m].is_number()) {
          values.push_back(run["metrics"][m].get<double>());
        }
      }
      if (values.empty()) {
        variant["stats"][m] = {{"n", 0}};
        continue;
      }
      const double n = static_cast<double>(values.size());
      double mean = 0;
      for (double v : values) mean += v / n;
      double var = 0;
      for (double v : values) var += (v - mean) * (v - mean);
      const double std_dev = values.size() > 1 ? std::sqrt(var / (n - 1)) : 0.0;
      variant["stats"][m] = {{"n", values.size()},
                             {"mean", mean},
                             {"std", std_dev},
                             {"min", *std::min_element(values.begin(), values.end())},
                             {"max", *std::max_element(values.begin(), values.end())},
                             {"worst", nullptr}};
    }
  }
  return data;
}

}  // namespace autodrive::scenarios::internal
