#include "maps/map_io.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <sstream>

#include "common/config.h"
#include "common/error.h"
#include "maps/builder.h"

namespace autodrive::maps {
namespace {

constexpr std::string_view kFormat = "autodrive-map/1";

double RingArea(const Polyline& ring) {
  double a = 0;
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const auto& p = ring[i];
    const auto& q = ring[(i + 1) % ring.size()];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return a / 2;
}

struct MapFile {
  std::string format;
  BuildOptions options;
  MapSummary summary;
  Layout layout;
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("format", format, config::OneOf{{std::string(kFormat)}});
    a.Required("options", options);
    a.Required("summary", summary);
    a.Required("layout", layout);
  }
};

}  // namespace

double Area(const std::vector<Region>& regions) {
  double total = 0;
  for (const auto& r : regions) {
    total += std::abs(RingArea(r.outer));
    for (const auto& h : r.holes) total -= std::abs(RingArea(h));
  }
  return total;
}

bool MapSummary::Matches(const MapSummary& o) const {
  const auto close = [](double a, double b) {
    return std::abs(a - b) <= 1e-9 * std::max({1.0, std::abs(a), std::abs(b)});
  };
  return rows == o.rows && cols == o.cols && lanes == o.lanes && intersections == o.intersections &&
         movements == o.movements && conflicts == o.conflicts && signal_heads == o.signal_heads &&
         signs == o.signs && obstacles == o.obstacles && close(road_area_m2, o.road_area_m2) &&
         close(drivable_area_m2, o.drivable_area_m2);
}

std::string MapSummary::ToString() const {
  std::ostringstream s;
  s << rows << "x" << cols << " tiles, lanes " << lanes << ", intersections " << intersections
    << ", movements " << movements << ", conflicts " << conflicts << ", signal heads "
    << signal_heads << ", signs " << signs << ", obstacles " << obstacles << ", road "
    << road_area_m2 << " m2, drivable " << drivable_area_m2 << " m2";
  return s.str();
}

MapSummary Summarise(const Map& map) {
  MapSummary s;
  s.rows = map.rows;
  s.cols = map.cols;
  s.lanes = static_cast<int>(map.lanes.size());
  s.intersections = static_cast<int>(map.intersections.size());
  s.movements = static_cast<int>(map.movements.size());
  for (const auto& x : map.intersections) s.conflicts += static_cast<int>(x.conflicts.size());
  s.signal_heads = static_cast<int>(map.signal_heads.size());
  s.signs = static_cast<int>(map.signs.size());
  s.obstacles = static_cast<int>(map.obstacles.size());
  s.road_area_m2 = Area(map.road_surface);
  s.drivable_area_m2 = Area(map.drivable);
  return s;
}

void SaveMap(const Map& map, const std::string& path) {
  MapFile f{std::string(kFormat), map.options, Summarise(map), map.layout};
  config::SaveFile(f, path);
}

Map LoadMap(const std::string& path) {
  const auto f = config::LoadFile<MapFile>(path);
  Map map = Build(f.layout, f.options);
  const MapSummary rebuilt = Summarise(map);
  AUTODRIVE_THROW_UNLESS(rebuilt.Matches(f.summary),
                         path << ": the map rebuilt from its layout differs from the one saved ("
                              << rebuilt.ToString() << " now, " << f.summary.ToString()
                              << " saved); the builder has changed since: rebuild it with "
                                 "autodrive-map build");
  return map;
}

Map LoadMapOrLayout(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception&) {
    // Let the strict loaders report it with file, line and column.
    return LoadMap(path);
  }
  if (root.IsMap() && root["grid"]) return Build(LoadLayout(path));
  return LoadMap(path);
}

}  // namespace autodrive::maps
