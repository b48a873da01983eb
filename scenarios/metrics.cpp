#include "scenarios/metrics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

#include <pugixml.hpp>

#include "scenarios/internal/lamp_bands.h"
#include "scenarios/internal/logs.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/error.h"
#include "maps/polyline.h"

namespace autodrive::scenarios {

namespace {

using Eigen::Vector2d;
using nlohmann::json;
constexpr double kInf = std::numeric_limits<double>::infinity();

json PointsToJson(const Points& p) {
  json a = json::array();
  for (const Vector2d& v : p) a.push_back({v.x(), v.y()});
  return a;
}
Points PointsFromJson(const json& a) {
  Points p;
  for (const auto& v : a) p.emplace_back(v.at(0).get<double>(), v.at(1).get<double>());
  return p;
}
json VecToJson(const Vector2d& v) { return {v.x(), v.y()}; }
Vector2d VecFromJson(const json& a) { return {a.at(0).get<double>(), a.at(1).get<double>()}; }

// ---- The logs ----

struct Sample {
  double t = 0, x = 0, y = 0, yaw = 0, vx = 0, vy = 0, yaw_rate = 0;
};

// Rows of a CSV file after its header, each with at least `columns` fields, with their line
// numbers.
std::vector<std::pair<std::size_t, std::vector<std::string>>> ReadCsv(
    const std::filesystem::path& file, std::size_t columns) {
  std::ifstream in(file);
  if (!in) throw InputError(fmt::format("{}: cannot read the log", file.string()));
  std::vector<std::pair<std::size_t, std::vector<std::string>>> rows;
  std::string line;
  std::getline(in, line);  // header
  for (std::size_t n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    auto fields = internal::SplitCsv(line);
    if (fields.size() < columns) {
      throw InputError(
          fmt::format("{}:{}: {} fields, expected {}", file.string(), n, fields.size(), columns));
    }
    rows.emplace_back(n, std::move(fields));
  }
  return rows;
}

std::vector<json> ReadJsonl(const std::filesystem::path& file) {
  std::vector<json> out;
  std::ifstream in(file);
  if (!in) return out;
  std::string line;
  for (std::size_t n = 1; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    try {
      out.push_back(json::parse(line));
    } catch (const json::exception& e) {
      throw InputError(fmt::format("{}:{}: {}", file.string(), n, e.what()));
    }
  }
  return out;
}

// Lamp states over time per head: (t, state) in time order.
using LampTrack = std::vector<std::pair<double, int>>;

int LampAt(const LampTrack& track, double t) {
  int state = 0;  // unknown: as dark
  for (const auto& [at, s] : track) {
    if (at > t + 1e-9) break;
    state = s;
  }
  return state;
}

// ---- Geometry ----

Points Footprint(const RunWorld::Car& car, const Sample& s) {
  return Rectangle(
      Vector2d(s.x, s.y) + car.centre_ahead_m * Vector2d(std::cos(s.yaw), std::sin(s.yaw)), s.yaw,
      car.length_m, car.width_m);
}

double SegmentDistance(const Vector2d& p, const Vector2d& a, const Vector2d& b) {
  const Vector2d d = b - a;
  const double n2 = d.squaredNorm();
  const double t = n2 > 0 ? std::clamp((p - a).dot(d) / n2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

double Cross(const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

bool SegmentsIntersect(const Vector2d& a, const Vector2d& b, const Vector2d& c, const Vector2d& d) {
  const double d1 = Cross(b - a, c - a), d2 = Cross(b - a, d - a);
  const double d3 = Cross(d - c, a - c), d4 = Cross(d - c, b - c);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}

bool Inside(const Vector2d& p, const Points& poly) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    if ((poly[i].y() > p.y()) != (poly[j].y() > p.y()) &&
        p.x() < (poly[j].x() - poly[i].x()) * (p.y() - poly[i].y()) / (poly[j].y() - poly[i].y()) +
                    poly[i].x()) {
      in = !in;
    }
  }
  return in;
}

struct Circle {
  Vector2d c;
  double r = 0;
};
Circle Bound(const Points& p) {
  Vector2d c = Vector2d::Zero();
  for (const auto& v : p) c += v;
  c /= static_cast<double>(p.size());
  double r = 0;
  for (const auto& v : p) r = std::max(r, (v - c).norm());
  return {c, r};
}

// The distance from p to the nearest segment of `line` whose direction is within 90° of
// `heading` (a lane driven the wrong way is not the car's lane).
double PolylineDistanceAlong(const Points& line, const Vector2d& p, const Vector2d& heading) {
  double best = kInf;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    if ((line[i + 1] - line[i]).dot(heading) <= 0) continue;
    best = std::min(best, SegmentDistance(p, line[i], line[i + 1]));
  }
  return best;
}

// Arc length along `line` of its point nearest to p, searched in [from, to] of arc length,
// with the distance.
std::pair<double, double> ProjectOnto(const Points& line, const Vector2d& p, double from,
                                      double to) {
  double at = 0, best_d = kInf, best_s = from;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Vector2d d = line[i + 1] - line[i];
    const double n = d.norm();
    if (n > 0 && at + n >= from && at <= to) {
      const double t = std::clamp((p - line[i]).dot(d) / (n * n), 0.0, 1.0);
      const double dist = (line[i] + t * d - p).norm();
      if (dist < best_d) {
        best_d = dist;
        best_s = at + t * n;
      }
    }
    at += n;
  }
  return {best_s, best_d};
}

double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const double rank = p / 100.0 * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(rank));
  const auto hi = static_cast<std::size_t>(std::ceil(rank));
  return v[lo] + (v[hi] - v[lo]) * (rank - static_cast<double>(lo));
}

// Numbers in reports: rounded to a micro-unit (the logs' resolution), so that a report is the
// same text for the same run; NaN (nothing to measure) as null.
json R(double x) {
  if (!std::isfinite(x)) return nullptr;
  return std::round(x * 1e6) / 1e6;
}

// ---- One car ----

struct Contact {
  double t = 0;
  std::string with;  ///< "nigel_2", "traffic:<id>", "wall:3", ...
  std::string kind;  ///< vehicle, traffic, wall, box, pole, obstacle
  double speed_mps = 0;
};

struct TrafficRow {
  std::string id;
  Points footprint;
  Vector2d velocity;
};

}  // namespace

RouteProgress::RouteProgress(const RunWorld::Car& car, const MetricConstants& k)
    : car_(&car),
      tolerance_m_(k.route_tolerance_m),
      goal_progress_m_(k.goal_progress_m),
      length_(maps::PolylineLength(car.route)) {}

void RouteProgress::Update(double x_m, double y_m) {
  if (car_->route.empty()) return;
  const auto [at, d] =
      ProjectOnto(car_->route, Vector2d(x_m, y_m), progress_ - 0.1, progress_ + 0.5);
  if (d <= tolerance_m_) progress_ = std::max(progress_, at);
}

bool RouteProgress::AtGoal(double x_m, double y_m, double yaw_rad) const {
  return !car_->route.empty() && progress_ >= length_ - goal_progress_m_ &&
         car_->AtGoal(x_m, y_m, yaw_rad);
}

json RunWorld::ToJson() const {
  json j;
  j["end_s"] = end_s;
  for (const Car& c : cars) {
    j["cars"].push_back(
        {{"name", c.name},
         {"length_m", c.length_m},
         {"width_m", c.width_m},
         {"centre_ahead_m", c.centre_ahead_m},
         {"top_speed_mps", c.top_speed_mps},
         {"goal_tolerance_m", c.goal_tolerance_m},
         {"goal_pose", c.goal_pose
                           ? json::array({c.goal_pose->x(), c.goal_pose->y(), c.goal_pose->z()})
                           : json(nullptr)},
         {"goal_tolerance_rad", c.goal_tolerance_rad},
         {"route", PointsToJson(c.route)},
         {"lap_ends_m", c.lap_ends_m}});
  }
  j["statics"] = json::array();
  for (const Static& s : statics) {
    j["statics"].push_back({{"kind", s.kind},
                            {"name", s.name},
                            {"footprint", PointsToJson(s.footprint)},
                            {"from_s", s.from_s},
                            {"until_s", s.until_s ? json(*s.until_s) : json(nullptr)}});
  }
  j["stop_lines"] = json::array();
  for (const StopLine& s : stop_lines) {
    j["stop_lines"].push_back({{"lane", s.lane},
                               {"intersection", s.intersection},
                               {"control", s.control},
                               {"heads", s.heads},
                               {"left", VecToJson(s.left)},
                               {"right", VecToJson(s.right)},
                               {"direction", VecToJson(s.direction)}});
  }
  j["lanes"] = json::array();
  for (const Lane& l : lanes) {
    j["lanes"].push_back(
        {{"name", l.name}, {"width_m", l.width_m}, {"centreline", PointsToJson(l.centreline)}});
  }
  j["open_floors"] = json::array();
  for (const Floor& f : open_floors) {
    j["open_floors"].push_back({{"min", VecToJson(f.min)}, {"max", VecToJson(f.max)}});
  }
  j["groups"] = json::array();
  for (const GroupHeads& g : groups) {
    j["groups"].push_back(
        {{"intersection", g.intersection}, {"group", g.group}, {"heads", g.heads}});
  }
  j["ingress"] = json::object();
  for (const auto& [key, r] : ingress) {
    j["ingress"][fmt::format("{}:{}", key.first, key.second)] = {{"intersection", r.intersection},
                                                                 {"heads", r.heads}};
  }
  return j;
}

RunWorld RunWorld::FromJson(const json& j) {
  RunWorld w;
  w.end_s = j.at("end_s").get<double>();
  for (const auto& c : j.at("cars")) {
    Car car;
    car.name = c.at("name").get<std::string>();
    car.length_m = c.at("length_m").get<double>();
    car.width_m = c.at("width_m").get<double>();
    car.centre_ahead_m = c.at("centre_ahead_m").get<double>();
    car.top_speed_mps = c.at("top_speed_mps").get<double>();
    car.goal_tolerance_m = c.at("goal_tolerance_m").get<double>();
    if (c.contains("goal_pose") && !c.at("goal_pose").is_null()) {
      const auto g = c.at("goal_pose").get<std::vector<double>>();
      AUTODRIVE_THROW_UNLESS(g.size() == 3, "world.json: goal_pose is not [x, y, yaw]");
      car.goal_pose = Eigen::Vector3d(g[0], g[1], g[2]);
      car.goal_tolerance_rad = c.value("goal_tolerance_rad", car.goal_tolerance_rad);
    }
    car.route = PointsFromJson(c.at("route"));
    if (c.contains("lap_ends_m")) car.lap_ends_m = c.at("lap_ends_m").get<std::vector<double>>();
    w.cars.push_back(std::move(car));
  }
  for (const auto& s : j.at("statics")) {
    Static st{s.at("kind").get<std::string>(), s.at("name").get<std::string>(),
              PointsFromJson(s.at("footprint"))};
    st.from_s = s.at("from_s").get<double>();
    if (!s.at("until_s").is_null()) st.until_s = s.at("until_s").get<double>();
    w.statics.push_back(std::move(st));
  }
  for (const auto& s : j.at("stop_lines")) {
    w.stop_lines.push_back(
        {s.at("lane").get<std::string>(), s.at("intersection").get<std::string>(),
         s.at("control").get<std::string>(), s.at("heads").get<std::vector<int>>(),
         VecFromJson(s.at("left")), VecFromJson(s.at("right")), VecFromJson(s.at("direction"))});
  }
  for (const auto& l : j.at("lanes")) {
    w.lanes.push_back({l.at("name").get<std::string>(), l.at("width_m").get<double>(),
                       PointsFromJson(l.at("centreline"))});
  }
  for (const auto& f : j.value("open_floors", json::array())) {  // not in older world.json
    w.open_floors.push_back({VecFromJson(f.at("min")), VecFromJson(f.at("max"))});
  }
  for (const auto& g : j.at("groups")) {
    w.groups.push_back({g.at("intersection").get<int>(), g.at("group").get<int>(),
                        g.at("heads").get<std::vector<int>>()});
  }
  for (const auto& [key, r] : j.at("ingress").items()) {
    const int lane = std::stoi(key.substr(key.find(':') + 1));
    w.ingress[{r.at("intersection").get<int>(), lane}] = {r.at("intersection").get<int>(), lane,
                                                          r.at("heads").get<std::vector<int>>()};
  }
  return w;
}

Points Rectangle(const Eigen::Vector2d& centre, double yaw, double length, double width) {
  const Vector2d f(std::cos(yaw), std::sin(yaw));
  const Vector2d l(-f.y(), f.x());
  const double hl = length / 2, hw = width / 2;
  return {centre - hl * f - hw * l, centre + hl * f - hw * l, centre + hl * f + hw * l,
          centre - hl * f + hw * l};
}

json SumoTripStatistics(const std::filesystem::path& tripinfo_file,
                        const std::set<std::string>& lab_cars) {
  if (!std::filesystem::exists(tripinfo_file)) return nullptr;
  // SUMO closes the file as its process ends; a process killed leaves it without its end tag.
  std::string text = config::ReadFile(tripinfo_file);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
  if (text.find("<tripinfos") != std::string::npos && !text.ends_with("</tripinfos>")) {
    return {{"unfinished", "SUMO did not finish the file (its process was killed)"}};
  }
  // The line of byte `offset` of the file (1 for the first), for refusals.
  const auto line_at = [&](std::ptrdiff_t offset) {
    return static_cast<std::size_t>(std::count(text.begin(), text.begin() + offset, '\n')) + 1;
  };
  pugi::xml_document doc;
  const pugi::xml_parse_result parsed = doc.load_string(text.c_str());
  if (!parsed) {
    throw InputError(fmt::format("{}:{}: not XML: {}", tripinfo_file.string(),
                                 line_at(parsed.offset), parsed.description()));
  }
  const pugi::xml_node root = doc.child("tripinfos");
  if (!root) {
    throw InputError(fmt::format("{}: no <tripinfos> element (not SUMO's --tripinfo-output)",
                                 tripinfo_file.string()));
  }
  const auto attribute = [&](const pugi::xml_node& trip, const char* name) {
    const std::string value = trip.attribute(name).as_string();
    try {
      return internal::Number(value, tripinfo_file, 0);
    } catch (const InputError&) {
      throw InputError(fmt::format("{}:{}: trip \"{}\": {} is \"{}\", not a number",
                                   tripinfo_file.string(), line_at(trip.offset_debug()),
                                   trip.attribute("id").as_string(), name, value));
    }
  };
  json per_car = json::object();
  int arrived = 0;
  long waiting_count = 0;
  std::vector<double> waiting, loss;
  for (const pugi::xml_node trip : root.children("tripinfo")) {
    const std::string id = trip.attribute("id").as_string();
    if (lab_cars.contains(id)) continue;
    if (per_car.contains(id)) {
      throw InputError(fmt::format("{}:{}: trip \"{}\" is there twice", tripinfo_file.string(),
                                   line_at(trip.offset_debug()), id));
    }
    const double arrival = attribute(trip, "arrival");
    const double wait = attribute(trip, "waitingTime"), lost = attribute(trip, "timeLoss");
    const auto count = static_cast<long>(attribute(trip, "waitingCount"));
    // SUMO writes arrival -1 for a car it closed on while it drove (write-unfinished).
    const bool done = arrival >= 0.0;
    arrived += done ? 1 : 0;
    waiting_count += count;
    waiting.push_back(wait);
    loss.push_back(lost);
    per_car[id] = {{"depart_s", R(attribute(trip, "depart"))},
                   {"arrived", done},
                   {"duration_s", R(attribute(trip, "duration"))},
                   {"waiting_time_s", R(wait)},
                   {"waiting_count", count},
                   {"time_loss_s", R(lost)}};
  }
  const auto mean = [](const std::vector<double>& v) {
    double sum = 0.0;
    for (const double x : v) sum += x;
    return v.empty() ? std::numeric_limits<double>::quiet_NaN()
                     : sum / static_cast<double>(v.size());
  };
  const auto max = [](const std::vector<double>& v) {
    return v.empty() ? std::numeric_limits<double>::quiet_NaN() : *std::ranges::max_element(v);
  };
  return {{"trips", waiting.size()},
          {"arrived", arrived},
          {"waiting_time_s", {{"mean", R(mean(waiting))}, {"max", R(max(waiting))}}},
          {"waiting_count", waiting_count},
          {"time_loss_s", {{"mean", R(mean(loss))}, {"max", R(max(loss))}}},
          {"per_car", per_car}};
}

double PolygonDistance(const Points& a, const Points& b) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = 0; j < b.size(); ++j) {
      if (SegmentsIntersect(a[i], a[(i + 1) % a.size()], b[j], b[(j + 1) % b.size()])) return 0;
    }
  }
  if (Inside(a.front(), b) || Inside(b.front(), a)) return 0;
  double best = kInf;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = 0; j < b.size(); ++j) {
      best = std::min(best, SegmentDistance(a[i], b[j], b[(j + 1) % b.size()]));
      best = std::min(best, SegmentDistance(b[j], a[i], a[(i + 1) % a.size()]));
    }
  }
  return best;
}

json ComputeMetrics(const RunWorld& world, const std::filesystem::path& logs_dir,
                    const MetricConstants& k) {
  // Ground truth per car, in time order.
  std::map<std::string, std::vector<Sample>> truth;
  for (const auto& [line, row] : ReadCsv(logs_dir / "ground_truth.csv", 8)) {
    const auto file = logs_dir / "ground_truth.csv";
    Sample s;
    s.t = internal::Number(row[0], file, line);
    s.x = internal::Number(row[2], file, line);
    s.y = internal::Number(row[3], file, line);
    s.yaw = internal::Number(row[4], file, line);
    s.vx = internal::Number(row[5], file, line);
    s.vy = internal::Number(row[6], file, line);
    s.yaw_rate = internal::Number(row[7], file, line);
    truth[row[1]].push_back(s);
  }
  std::map<int, LampTrack> lamps;
  for (const auto& [line, row] : ReadCsv(logs_dir / "lamps.csv", 3)) {
    const auto file = logs_dir / "lamps.csv";
    lamps[static_cast<int>(internal::Number(row[1], file, line))].emplace_back(
        internal::Number(row[0], file, line),
        static_cast<int>(internal::Number(row[2], file, line)));
  }
  // What each head showed over time: steady aspects, and flashing ones told from their
  // alternation (a flashing red is judged by the stop-sign rule).
  std::map<int, std::vector<internal::LampBand>> bands;
  for (const auto& [head, track] : lamps) {
    bands[head] = internal::LampBands(track, std::max(world.end_s, track.back().first));
  }
  // SUMO's cars per stamp.
  std::map<double, std::vector<TrafficRow>> traffic;
  if (std::filesystem::exists(logs_dir / "traffic.csv")) {
    const auto file = logs_dir / "traffic.csv";
    for (const auto& [line, row] : ReadCsv(file, 10)) {
      const double yaw = internal::Number(row[5], file, line),
                   v = internal::Number(row[8], file, line);
      traffic[internal::Number(row[0], file, line)].push_back(
          {row[1],
           Rectangle({internal::Number(row[3], file, line), internal::Number(row[4], file, line)},
                     yaw, internal::Number(row[6], file, line),
                     internal::Number(row[7], file, line)),
           v * Vector2d(std::cos(yaw), std::sin(yaw))});
    }
  }
  std::vector<Circle> static_bounds;
  std::vector<std::string> static_keys;
  for (const auto& s : world.statics) {
    static_bounds.push_back(Bound(s.footprint));
    static_keys.push_back(s.kind + ":" + s.name);
  }

  json vehicles = json::object();
  // Car-car contacts are found once per pair and given to both.
  std::map<std::string, std::vector<Contact>> contacts;
  for (std::size_t ci = 0; ci < world.cars.size(); ++ci) {
    const RunWorld::Car& car = world.cars[ci];
    const std::vector<Sample>& samples = truth[car.name];
    // last contact time and whether in contact, per other thing
    std::map<std::string, std::pair<bool, double>> touching;
    const auto touch = [&](const std::string& with, const std::string& kind, double distance,
                           double t, double speed, const std::string* other_car) {
      auto& [in, last] = touching[with];
      if (distance <= k.contact_m) {
        if (!in && (last == 0.0 || t - last >= k.rearm_s)) {
          contacts[car.name].push_back({t, with, kind, speed});
          if (other_car != nullptr) contacts[*other_car].push_back({t, car.name, kind, speed});
        }
        in = true;
        last = t;
      } else if (distance > k.separation_m) {
        if (in) last = t;
        in = false;
      } else if (in) {
        last = t;
      }
    };
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const Sample& s = samples[i];
      const Points fp = Footprint(car, s);
      const Circle cb = Bound(fp);
      const Vector2d v_car = s.vx * Vector2d(std::cos(s.yaw), std::sin(s.yaw));
      for (std::size_t o = 0; o < world.statics.size(); ++o) {
        const std::string& key = static_keys[o];
        if (!world.statics[o].StandsAt(s.t) ||
            (static_bounds[o].c - cb.c).norm() > static_bounds[o].r + cb.r + k.separation_m) {
          const auto it = touching.find(key);
          if (it != touching.end() && it->second.first) {
            touch(key, world.statics[o].kind, kInf, s.t, 0, nullptr);
          }
          continue;
        }
        touch(key, world.statics[o].kind, PolygonDistance(fp, world.statics[o].footprint), s.t,
              std::abs(s.vx), nullptr);
      }
      for (std::size_t cj = ci + 1; cj < world.cars.size(); ++cj) {
        const auto& other = truth[world.cars[cj].name];
        if (i >= other.size()) continue;
        const Sample& so = other[i];
        const Points ofp = Footprint(world.cars[cj], so);
        const Vector2d v_other = so.vx * Vector2d(std::cos(so.yaw), std::sin(so.yaw));
        touch(world.cars[cj].name, "vehicle", PolygonDistance(fp, ofp), s.t,
              (v_car - v_other).norm(), &world.cars[cj].name);
      }
      if (!traffic.empty()) {
        auto it = traffic.upper_bound(s.t + 1e-9);
        if (it != traffic.begin()) {
          --it;
          for (const TrafficRow& r : it->second) {
            const Circle rb = Bound(r.footprint);
            const double d = (rb.c - cb.c).norm() > rb.r + cb.r + k.separation_m
                                 ? kInf
                                 : PolygonDistance(fp, r.footprint);
            touch("traffic:" + r.id, "traffic", d, s.t, (v_car - r.velocity).norm(), nullptr);
          }
        }
      }
    }
  }

  json run_collisions = json::array();
  std::set<std::tuple<double, std::string, std::string>> pairs_seen;
  double total_distance = 0;
  int total_red = 0, total_stop = 0, total_departures = 0, total_stops = 0, goals_reached = 0;
  double min_completion = kInf, max_time_to_goal = -kInf, min_score = kInf, stopped_total = 0,
         loss_total = 0, max_accel = 0, max_jerk = 0, energy_total = 0;
  int cars_with_route = 0;
  for (const RunWorld::Car& car : world.cars) {
    const std::vector<Sample>& samples = truth[car.name];
    json v;
    // Distance, stops, time loss, comfort, energy.
    double distance = 0, stopped = 0, loss = 0, energy = 0;
    int stops = 0;
    bool moving = false, moved = false;
    std::optional<double> goal_t;
    // Route: progress along it, goal.
    RouteProgress route(car, k);
    const double route_length = route.length_m();
    std::vector<double> lap_ends_t;  // when each lap's end was passed
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const Sample& s = samples[i];
      const double speed = std::abs(s.vx);
      const double dt = i > 0 ? s.t - samples[i - 1].t : 0.0;
      if (i > 0) {
        const double step =
            (Vector2d(s.x, s.y) - Vector2d(samples[i - 1].x, samples[i - 1].y)).norm();
        distance += step;
        const double dke = 0.5 * (s.vx * s.vx - samples[i - 1].vx * samples[i - 1].vx);
        energy += std::max(0.0, dke) + 9.81 * k.rolling_resistance * step;
      }
      if (speed > k.moving_mps) {
        moving = true;
        moved = true;
      } else if (speed < k.stopped_mps && moving) {
        moving = false;
        if (!goal_t) ++stops;
      }
      if (moved && !goal_t && i > 0) {
        if (speed < k.stopped_mps) stopped += dt;
        loss += dt * (1.0 - std::min(speed / car.top_speed_mps, 1.0));
      }
      if (!car.route.empty()) {
        route.Update(s.x, s.y);
        const double progress = route.progress_m();
        if (!goal_t && route.AtGoal(s.x, s.y, s.yaw)) goal_t = s.t;
        const std::size_t lap = lap_ends_t.size();
        if (lap < car.lap_ends_m.size() &&
            (progress >= car.lap_ends_m[lap] || (goal_t && lap + 1 == car.lap_ends_m.size()))) {
          lap_ends_t.push_back(s.t);
        }
      } else if (car.goal_pose && !goal_t && speed < k.stopped_mps && car.AtGoal(s.x, s.y, s.yaw)) {
        goal_t = s.t;  // a goal pose: reached standing there
      }
    }
    // Comfort: acceleration over 1 s windows (speed now minus 1 s ago), jerk likewise.
    double accel_max = 0, jerk_max = 0, lat_max = 0;
    {
      std::vector<double> a(samples.size(), std::numeric_limits<double>::quiet_NaN());
      std::size_t back = 0, back_a = 0;
      for (std::size_t i = 0; i < samples.size(); ++i) {
        while (back < i && samples[i].t - samples[back + 1].t >= 1.0 - 1e-9) ++back;
        if (samples[i].t - samples[back].t >= 1.0 - 1e-9) {
          a[i] = (samples[i].vx - samples[back].vx) / (samples[i].t - samples[back].t);
          accel_max = std::max(accel_max, std::abs(a[i]));
          while (back_a < i && samples[i].t - samples[back_a + 1].t >= 1.0 - 1e-9) ++back_a;
          if (!std::isnan(a[back_a]) && samples[i].t - samples[back_a].t >= 1.0 - 1e-9) {
            jerk_max =
                std::max(jerk_max, std::abs(a[i] - a[back_a]) / (samples[i].t - samples[back_a].t));
          }
        }
        lat_max = std::max(lat_max, std::abs(samples[i].vx * samples[i].yaw_rate));
      }
    }
    // Red lights and stop signs, at each stop line the car crosses.
    json red = json::array(), stop_signs = json::array();
    const double tail_behind = car.length_m / 2 - car.centre_ahead_m;
    const double front_ahead = car.centre_ahead_m + car.length_m / 2;
    for (const RunWorld::StopLine& line : world.stop_lines) {
      const Vector2d mid = (line.left + line.right) / 2;
      const double half = (line.left - line.right).norm() / 2;
      const Vector2d across = (line.left - line.right).normalized();
      const auto signed_at = [&](const Sample& s, double ahead) {
        const Vector2d p = Vector2d(s.x, s.y) + ahead * Vector2d(std::cos(s.yaw), std::sin(s.yaw));
        return std::pair{(p - mid).dot(line.direction), std::abs((p - mid).dot(across))};
      };
      // The aspect of the first facing head that has one at `t` (-1: none known).
      const auto aspect_at = [&](double t, int& head) {
        for (int h : line.heads) {
          const auto it = bands.find(h);
          if (it == bands.end() || it->second.empty() || it->second.front().from_s > t + 1e-9) {
            continue;
          }
          head = h;
          return internal::AspectAt(it->second, t);
        }
        return -1;
      };
      for (std::size_t i = 1; i < samples.size(); ++i) {
        if (line.control == "signal") {
          // The tail crosses the line on steady red (ScenarioRunner's RunningRedLightTest).
          const auto [before, lat0] = signed_at(samples[i - 1], -tail_behind);
          const auto [after, lat1] = signed_at(samples[i], -tail_behind);
          if (before < 0 && after >= 0 && lat1 <= half + 0.02) {
            for (int h : line.heads) {
              const auto it = bands.find(h);
              if (it == bands.end() || internal::AspectAt(it->second, samples[i].t) != 1) {
                continue;
              }
              red.push_back({{"t_s", R(samples[i].t)},
                             {"intersection", line.intersection},
                             {"lane", line.lane},
                             {"head", h},
                             {"speed_mps", R(std::abs(samples[i].vx))}});
              break;
            }
          }
        }
        // The front crosses a stop sign's line, or a signal's while it flashes red or is dark
        // (an all-way stop by law): was there a full stop within the zone before it
        // (ScenarioRunner's RunningStopTest)?
        const auto [before, lat0] = signed_at(samples[i - 1], front_ahead);
        const auto [after, lat1] = signed_at(samples[i], front_ahead);
        if (!(before < 0 && after >= 0 && lat1 <= half + 0.02)) continue;
        std::string control = "stop";
        int head = 0;
        if (line.control == "signal") {
          const int aspect = aspect_at(samples[i].t, head);
          if (aspect != 4 && aspect != 0) continue;
          control = aspect == 4 ? "flashing_red" : "dark";
        }
        double slowest = kInf;
        for (std::size_t j = i; j-- > 0;) {
          const auto [at, lat] = signed_at(samples[j], front_ahead);
          if (at < -k.stop_zone_m) break;
          slowest = std::min(slowest, std::abs(samples[j].vx));
        }
        if (slowest >= k.stopped_mps) {
          json violation{{"t_s", R(samples[i].t)},
                         {"intersection", line.intersection},
                         {"lane", line.lane},
                         {"min_speed_mps", R(slowest)}};
          if (control != "stop") {
            violation["control"] = control;
            violation["head"] = head;
          }
          stop_signs.push_back(std::move(violation));
        }
      }
    }
    // Lane departures: the footprint's centre further than half a lane's width from every
    // lane and movement centre line, and not on an open floor.
    json departures = json::array();
    double off_distance = 0;
    {
      std::vector<Circle> lane_bounds;
      for (const auto& l : world.lanes) lane_bounds.push_back(Bound(l.centreline));
      bool off = false;
      double back_on_since = 0, worst = 0;
      for (std::size_t i = 0; i < samples.size(); ++i) {
        const Sample& s = samples[i];
        const Vector2d heading(std::cos(s.yaw), std::sin(s.yaw));
        const Vector2d c = Vector2d(s.x, s.y) + car.centre_ahead_m * heading;
        double excess = kInf;
        for (const RunWorld::Floor& f : world.open_floors) {
          if (f.Contains(c)) excess = 0;
        }
        for (std::size_t l = 0; l < world.lanes.size() && excess > 0; ++l) {
          if ((lane_bounds[l].c - c).norm() > lane_bounds[l].r + world.lanes[l].width_m) continue;
          excess = std::min(excess, PolylineDistanceAlong(world.lanes[l].centreline, c, heading) -
                                        world.lanes[l].width_m / 2);
        }
        const bool now_off = excess > 0;
        if (now_off && i > 0) {
          off_distance +=
              (Vector2d(s.x, s.y) - Vector2d(samples[i - 1].x, samples[i - 1].y)).norm();
        }
        if (now_off && !off) {
          if (departures.empty() || s.t - back_on_since >= k.departure_rearm_s) {
            departures.push_back({{"t_s", R(s.t)}, {"duration_s", 0.0}, {"max_offset_m", 0.0}});
            worst = 0;
          }
          off = true;
        }
        if (now_off) {
          worst = std::min(std::max(worst, excess), 10.0);
          departures.back()["max_offset_m"] = R(worst);
          departures.back()["duration_s"] = R(s.t - departures.back()["t_s"].get<double>());
        } else if (off) {
          off = false;
          back_on_since = s.t;
        }
      }
    }
    // Collisions of this car.
    json collisions = json::array();
    auto& mine = contacts[car.name];
    std::sort(mine.begin(), mine.end(), [](const Contact& a, const Contact& b) {
      return std::tie(a.t, a.with) < std::tie(b.t, b.with);
    });
    int car_hits = 0, static_hits = 0;
    for (const Contact& c : mine) {
      collisions.push_back(
          {{"t_s", R(c.t)}, {"with", c.with}, {"kind", c.kind}, {"speed_mps", R(c.speed_mps)}});
      if (c.kind == "vehicle" || c.kind == "traffic") {
        ++car_hits;
      } else {
        ++static_hits;
      }
      const std::string a = std::min(car.name, c.with), b = std::max(car.name, c.with);
      if (pairs_seen.insert({c.t, a, b}).second) {
        run_collisions.push_back({{"t_s", R(c.t)},
                                  {"vehicle", car.name},
                                  {"with", c.with},
                                  {"kind", c.kind},
                                  {"speed_mps", R(c.speed_mps)}});
      }
    }
    const double completion =
        car.goal_pose ? (goal_t ? 1.0 : 0.0)
        : car.route.empty()
            ? 1.0
            : (goal_t ? 1.0 : std::min(route.progress_m() / std::max(route_length, 1e-9), 1.0));
    const double off_fraction = distance > 0 ? std::min(off_distance / distance, 1.0) : 0.0;
    const auto n_red = static_cast<int>(red.size());
    const auto n_stop = static_cast<int>(stop_signs.size());
    const auto n_dep = static_cast<int>(departures.size());
    const double penalty = std::pow(0.6, car_hits) * std::pow(0.65, static_hits) *
                           std::pow(0.7, n_red) * std::pow(0.8, n_stop);
    const double score = completion * (1.0 - off_fraction) * penalty;
    const int infractions = static_cast<int>(mine.size()) + n_red + n_stop + n_dep;
    const double full_scale_km = distance * k.scale / 1000.0;
    v["distance_m"] = R(distance);
    v["collisions"] = collisions;
    v["red_light_violations"] = red;
    v["stop_sign_violations"] = stop_signs;
    v["lane_departures"] = departures;
    v["off_lane_fraction"] = R(off_fraction);
    v["route_length_m"] = R(route_length);
    v["route_completion"] = R(completion);
    v["goal_reached"] = goal_t.has_value();
    if (!car.lap_ends_m.empty()) {
      // Each lap's time: from the start (the first lap) or the end of the lap before.
      json laps = json::array();
      for (std::size_t l = 0; l < lap_ends_t.size(); ++l) {
        laps.push_back(R(lap_ends_t[l] - (l == 0 ? 0.0 : lap_ends_t[l - 1])));
      }
      v["laps_completed"] = static_cast<int>(lap_ends_t.size());
      v["lap_times_s"] = laps;
    }
    if (car.goal_pose && !samples.empty()) {
      // Where it ended against the goal pose.
      const Sample& last = samples.back();
      v["final_position_error_m"] = R((Vector2d(last.x, last.y) - car.goal_pose->head<2>()).norm());
      v["final_heading_error_deg"] =
          R(std::abs(std::remainder(last.yaw - car.goal_pose->z(), 2 * std::numbers::pi)) * 180 /
            std::numbers::pi);
    }
    v["time_to_goal_s"] = goal_t ? R(*goal_t) : json(nullptr);
    v["delay_s"] = goal_t && !car.route.empty() ? R(*goal_t - route_length / car.top_speed_mps)
                                                : json(nullptr);
    v["time_loss_s"] = R(loss);
    v["stops"] = stops;
    v["stopped_time_s"] = R(stopped);
    v["max_accel_mps2"] = R(accel_max);
    v["max_jerk_mps3"] = R(jerk_max);
    v["max_lateral_accel_mps2"] = R(lat_max);
    v["energy_j_per_kg"] = R(energy);
    v["infractions"] = infractions;
    v["infractions_per_km"] = full_scale_km > 0 ? R(infractions / full_scale_km) : json(0.0);
    v["penalty"] = R(penalty);
    v["score"] = R(score);
    vehicles[car.name] = v;

    total_distance += distance;
    total_red += n_red;
    total_stop += n_stop;
    total_departures += n_dep;
    total_stops += stops;
    stopped_total += stopped;
    loss_total += loss;
    energy_total += energy;
    max_accel = std::max(max_accel, accel_max);
    max_jerk = std::max(max_jerk, jerk_max);
    min_score = std::min(min_score, score);
    if (car.HasGoal()) {  // a route, or a goal pose
      ++cars_with_route;
      min_completion = std::min(min_completion, completion);
      if (goal_t) {
        ++goals_reached;
        max_time_to_goal = std::max(max_time_to_goal, *goal_t);
      }
    }
  }

  // The lockstep's step, from the ground truth's rows (a lamp shows what the SCM decided one
  // step later).
  double step = 0.01;
  for (const auto& [name, samples] : truth) {
    if (samples.size() > 1) step = samples[1].t - samples[0].t;
    break;
  }
  // V2I: SPaT's rate in every whole second, its min-end and max-end against the lamps.
  json v2i;
  const auto spat = ReadJsonl(logs_dir / "spat.jsonl");
  std::map<int, std::vector<double>> spat_times;
  std::vector<double> min_end_errors, max_end_errors;
  int min_end_broken = 0;
  std::map<std::pair<int, int>, std::vector<int>> group_heads;
  for (const auto& g : world.groups) group_heads[{g.intersection, g.group}] = g.heads;
  // The first time after t at which a head of the group shows another lamp than at t.
  const auto change_after = [&](const std::vector<int>& heads, double t) {
    double first = kInf;
    for (int h : heads) {
      const LampTrack& track = lamps[h];
      const int now = LampAt(track, t);
      for (const auto& [at, s] : track) {
        if (at > t + 1e-9 && s != now) {
          first = std::min(first, at);
          break;
        }
      }
    }
    return first;
  };
  for (const json& m : spat) {
    const int x = m.at("intersection").get<int>();
    const double t = m.at("t_s").get<double>();
    spat_times[x].push_back(t);
    for (const json& g : m.at("groups")) {
      // Steady states only: a flashing or dark group has no end to predict (its lamps blink).
      const int state = g.at("state").get<int>();
      if (state != 3 && state != 5 && state != 6 && state != 7 && state != 8) continue;
      const auto it = group_heads.find({x, g.at("group").get<int>()});
      if (it == group_heads.end()) continue;
      const double change = change_after(it->second, t);
      if (!std::isfinite(change)) continue;  // not seen to end before the run did
      const double min_error = change - g.at("min_end_s").get<double>();
      min_end_errors.push_back(min_error);
      if (min_error < -1.1 * step) ++min_end_broken;  // more than a step early (lamps lag one)
      if (g.contains("max_end_s"))
        max_end_errors.push_back(g.at("max_end_s").get<double>() - change);
    }
  }
  int windows = 0, windows_low = 0;
  double min_rate = kInf;
  json spat_rates = json::object();
  for (const auto& [x, times] : spat_times) {
    const double first = std::ceil(times.front() - 1e-9);
    int x_windows = 0, x_low = 0, x_min = std::numeric_limits<int>::max();
    for (double w = first; w + 1.0 <= world.end_s + 1e-9; w += 1.0) {
      const auto n = std::count_if(times.begin(), times.end(),
                                   [&](double t) { return t >= w - 1e-9 && t < w + 1.0 - 1e-9; });
      ++x_windows;
      if (n < 10) ++x_low;
      x_min = std::min(x_min, static_cast<int>(n));
    }
    windows += x_windows;
    windows_low += x_low;
    if (x_windows > 0) min_rate = std::min(min_rate, static_cast<double>(x_min));
    spat_rates[std::to_string(x)] = {
        {"messages", times.size()},
        {"windows", x_windows},
        {"windows_below_10hz", x_low},
        {"min_per_window", x_windows > 0 ? json(x_min) : json(nullptr)}};
  }
  v2i["spat"] = {{"messages", spat.size()},
                 {"windows", windows},
                 {"windows_below_10hz", windows_low},
                 {"min_rate_hz", R(min_rate)},
                 {"per_intersection", spat_rates},
                 {"min_end_error_p50_s", R(Percentile(min_end_errors, 50))},
                 {"min_end_error_p95_s", R(Percentile(min_end_errors, 95))},
                 {"min_end_broken", min_end_broken},
                 {"max_end_error_p50_s", R(Percentile(max_end_errors, 50))},
                 {"max_end_error_p95_s", R(Percentile(max_end_errors, 95))},
                 {"predictions", min_end_errors.size()}};
  v2i["map_messages"] = ReadJsonl(logs_dir / "map.jsonl").size();
  // Requests: outcomes (the last status of each) and request-to-green latency from the lamps.
  const auto requests = ReadJsonl(logs_dir / "requests.jsonl");
  std::map<std::pair<std::string, std::uint32_t>, int> outcome;
  json request_list = json::array();
  double request_to_green_max = -kInf;
  int n_requests = 0;
  for (const json& r : requests) {
    const auto key =
        std::pair{r.at("vehicle").get<std::string>(), r.at("request_id").get<std::uint32_t>()};
    if (r.at("kind") == "status") {
      // The first final answer (completed, rejected, cancelled) stands: an answer after it is
      // to another message with the same id (a cancel of a request already served).
      const auto it = outcome.find(key);
      if (it == outcome.end() || it->second < 3) outcome[key] = r.at("status").get<int>();
      continue;
    }
    const int type = r.at("type").get<int>();
    if (type != 1 && type != 2) continue;  // priority or pre-emption
    ++n_requests;
    const double t = r.at("t_s").get<double>();
    double green = kInf;
    const auto in =
        world.ingress.find({r.at("intersection").get<int>(), r.at("in_lane").get<int>()});
    if (in != world.ingress.end()) {
      for (int h : in->second.heads) {
        if (LampAt(lamps[h], t) == 3) green = t;
        for (const auto& [at, s] : lamps[h]) {
          if (at > t && s == 3) {
            green = std::min(green, at);
            break;
          }
        }
      }
    }
    if (std::isfinite(green)) request_to_green_max = std::max(request_to_green_max, green - t);
    request_list.push_back({{"t_s", R(t)},
                            {"vehicle", key.first},
                            {"request_id", key.second},
                            {"type", type == 2 ? "preemption" : "priority"},
                            {"to_green_s", std::isfinite(green) ? R(green - t) : json(nullptr)}});
  }
  json outcomes = {{"granted", 0},   {"rejected", 0}, {"completed", 0},
                   {"cancelled", 0}, {"received", 0}, {"processing", 0}};
  int granted = 0;
  for (json& r : request_list) {
    const auto it =
        outcome.find({r["vehicle"].get<std::string>(), r["request_id"].get<std::uint32_t>()});
    const std::string o =
        it == outcome.end() || it->second < 0 || it->second > 5
            ? "unanswered"
            : std::string(dds::SignalRequestStatusName(static_cast<std::uint8_t>(it->second)));
    r["outcome"] = o;
    outcomes[o] = outcomes.value(o, 0) + 1;
    // granted, or served and then completed
    if (o == "granted" || o == "completed") ++granted;
  }
  v2i["requests"] = request_list;
  v2i["request_outcomes"] = outcomes;

  const int total_collisions = static_cast<int>(run_collisions.size());
  json run;
  run["collisions"] = total_collisions;
  run["collision_list"] = run_collisions;
  run["red_light_violations"] = total_red;
  run["stop_sign_violations"] = total_stop;
  run["lane_departures"] = total_departures;
  run["infractions"] = total_collisions + total_red + total_stop + total_departures;
  run["route_completion"] = cars_with_route > 0 ? R(min_completion) : json(nullptr);
  run["goals_reached"] = goals_reached;
  run["time_to_goal_s"] = goals_reached > 0 ? R(max_time_to_goal) : json(nullptr);
  run["distance_m"] = R(total_distance);
  run["infractions_per_km"] =
      total_distance > 0 ? R((total_collisions + total_red + total_stop + total_departures) /
                             (total_distance * k.scale / 1000.0))
                         : json(0.0);
  run["score"] = R(min_score);
  run["stops"] = total_stops;
  run["stopped_time_s"] = R(stopped_total);
  run["time_loss_s"] = R(loss_total);
  run["max_accel_mps2"] = R(max_accel);
  run["max_jerk_mps3"] = R(max_jerk);
  run["energy_j_per_kg"] = R(energy_total);
  run["spat_messages"] = spat.size();
  run["spat_windows_below_10hz"] = windows_low;
  run["spat_min_end_error_p95_s"] = R(Percentile(min_end_errors, 95));
  run["map_messages"] = v2i["map_messages"];
  run["requests"] = n_requests;
  run["requests_granted"] = granted;
  run["request_to_green_max_s"] =
      std::isfinite(request_to_green_max) ? R(request_to_green_max) : json(nullptr);
  // SUMO's background cars, as SUMO counts them.
  std::set<std::string> lab_cars;
  for (const RunWorld::Car& car : world.cars) lab_cars.insert(car.name);
  const json background = SumoTripStatistics(logs_dir / kTripinfoFile, lab_cars);
  if (background.contains("trips")) {
    run["background_trips"] = background["trips"];
    run["background_waiting_time_mean_s"] = background["waiting_time_s"]["mean"];
    run["background_time_loss_mean_s"] = background["time_loss_s"]["mean"];
  }
  return {{"vehicles", vehicles}, {"run", run}, {"v2i", v2i}, {"background", background}};
}

}  // namespace autodrive::scenarios
