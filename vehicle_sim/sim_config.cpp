#include "vehicle_sim/sim_config.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <numbers>
#include <set>
#include <utility>

#include "common/camera/roof_tag.h"
#include "common/error.h"
#include "common/ids.h"
#include "maps/map.h"
#include "maps/polyline.h"

namespace autodrive::vehicle_sim {

void SpawnConfig::Validate() const {
  const bool pose = x_m || y_m || yaw_rad;
  AUTODRIVE_THROW_UNLESS(lane.has_value() != pose,
                         "give either lane (and along_m) or x_m, y_m and yaw_rad");
  AUTODRIVE_THROW_UNLESS(!pose || (x_m && y_m && yaw_rad),
                         "a pose needs all of x_m, y_m and yaw_rad");
}

void UnmappedObstacle::Validate() const {
  AUTODRIVE_THROW_UNLESS(!until_s || *until_s > from_s,
                         "until_s (" << ToSeconds(until_s.value_or(Duration{}))
                                     << " s) must come after from_s (" << ToSeconds(from_s)
                                     << " s)");
}

void SimVehicleConfig::Validate() const { (void)ParseVehicleName(name); }

void ServiceOptions::Validate() const {
  AUTODRIVE_THROW_UNLESS(mode != SimMode::kLockstep || !controllers.empty() || !stages.empty(),
                         "controllers: lockstep needs at least one controller to wait for "
                         "(sim.service.controllers or stages, or --controller NAME)");
  AUTODRIVE_THROW_UNLESS(mode == SimMode::kLockstep || stages.empty(),
                         "stages: only lockstep has stages of controllers");
  std::set<std::string> names;
  const auto check = [&names](const std::string& c, std::string_view key) {
    AUTODRIVE_THROW_UNLESS(!c.empty(), key << ": a controller's name cannot be empty");
    AUTODRIVE_THROW_UNLESS(
        c != "end" && c.find(',') == std::string::npos,
        key << ": a controller cannot be named '" << c << "' (not 'end', no comma)");
    AUTODRIVE_THROW_UNLESS(names.insert(c).second, key << ": " << c << " is listed twice");
  };
  for (const auto& stage : stages) {
    AUTODRIVE_THROW_UNLESS(!stage.empty(), "stages: a stage cannot be empty");
    for (const std::string& c : stage) check(c, "stages");
  }
  for (const std::string& c : controllers) check(c, "controllers");
}

namespace {
// A figure given, else its value in the preset: the parking study's (`paper`) and the
// behavioural-cloning study's (`cloning`, which keeps the parking study's command noise).
double Preset(const std::optional<double>& given, VariabilityPreset preset, double paper,
              double cloning) {
  if (given) return *given;
  switch (preset) {
    case VariabilityPreset::kPaper:
      return paper;
    case VariabilityPreset::kCloning:
      return cloning;
    case VariabilityPreset::kNone:
      break;
  }
  return 0.0;
}

// SplitMix64's finaliser.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
}  // namespace

std::uint64_t StreamSeed(std::uint64_t seed, int vehicle, int stream) {
  return Mix(Mix(Mix(seed) ^ static_cast<std::uint64_t>(vehicle)) ^
             static_cast<std::uint64_t>(stream));
}

double Gaussian(std::mt19937_64& rng, double sigma) {
  if (sigma == 0.0) return 0.0;
  return std::normal_distribution<double>(0.0, sigma)(rng);
}

// The papers' figures (NIGEL.md, "Variability used in the paper's parking study" and the
// behavioural-cloning study beside it).
double VariabilityConfig::DriveNoiseMps() const {
  return Preset(drive_noise_mps, preset, 0.013, 0.013);
}
double VariabilityConfig::SteeringNoiseRad() const {
  return Preset(steering_noise_rad, preset, 0.018, 0.018);
}
double VariabilityConfig::WallPositionNoiseM() const {
  return Preset(wall_position_noise_m, preset, 0.01, 0.0);
}
double VariabilityConfig::WallHeadingNoiseRad() const {
  return Preset(wall_heading_noise_rad, preset, 0.087, 0.0);
}
double VariabilityConfig::LidarRangeNoiseM() const {
  return Preset(lidar_range_noise_m, preset, 0.025, 0.0);
}
int VariabilityConfig::RandomObstacles() const {
  if (random_obstacles) return *random_obstacles;
  return preset == VariabilityPreset::kPaper ? 3 : 0;
}
double VariabilityConfig::LightIntensitySpread() const {
  return Preset(light_intensity_spread, preset, 0.0, 0.4);
}
double VariabilityConfig::LightDirectionSpreadRad() const {
  return Preset(light_direction_spread_rad, preset, 0.0, std::numbers::pi);
}
double VariabilityConfig::StartPositionNoiseM() const {
  return Preset(start_position_noise_m, preset, 0.0, 0.03);
}
double VariabilityConfig::StartHeadingNoiseRad() const {
  return Preset(start_heading_noise_rad, preset, 0.0, 0.087);
}

void SimConfig::Validate() const {
  AUTODRIVE_THROW_UNLESS(!vehicles.empty(), "vehicles: at least one car");
  std::set<std::string> names;
  for (const SimVehicleConfig& v : vehicles) {
    AUTODRIVE_THROW_UNLESS(names.insert(v.name).second, "vehicle " << v.name << " is listed twice");
  }
  std::set<std::string> camera_names;
  for (const OverheadCameraConfig& c : cameras) {
    AUTODRIVE_THROW_UNLESS(camera_names.insert(c.name).second,
                           "cameras: " << c.name << " is listed twice");
  }
  std::set<std::string> obstacle_names;
  for (const UnmappedObstacle& o : variability.obstacles) {
    AUTODRIVE_THROW_UNLESS(o.name.empty() || obstacle_names.insert(o.name).second,
                           "variability.obstacles: " << o.name << " is listed twice");
  }
  // A tag id seen twice would make the Eye see one car (or reference) in two places.
  std::map<std::pair<std::string, int>, std::string> tags;
  const auto add = [&](const TagSpec& tag, const std::string& owner) {
    const auto [it, fresh] = tags.try_emplace({tag.family, tag.id}, owner);
    AUTODRIVE_THROW_UNLESS(fresh, "tag " << tag.family << " id " << tag.id << " is on both "
                                         << it->second << " and " << owner);
  };
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const VehicleLook look = EffectiveLook(*this, i);
    if (look.tag) add(*look.tag, vehicles[i].name + "'s roof");
  }
  for (std::size_t i = 0; i < ground_tags.size(); ++i) {
    add(ground_tags[i].tag, "ground_tags[" + std::to_string(i) + "]");
  }
}

VehicleLook EffectiveLook(const SimConfig& sim, std::size_t i) {
  static constexpr std::array<Rgb, 8> kPalette{
      Rgb{200, 30, 30},  Rgb{30, 90, 200},  Rgb{240, 200, 30}, Rgb{30, 160, 60},
      Rgb{150, 60, 190}, Rgb{240, 130, 20}, Rgb{20, 170, 180}, Rgb{230, 230, 230}};
  const SimVehicleConfig& v = sim.vehicles.at(i);
  VehicleLook look;
  look.colour = v.look.colour.value_or(kPalette[i % kPalette.size()]);
  if (v.look.roof_tag) {
    TagSpec tag{"tag36h11", static_cast<int>(ParseVehicleName(v.name).value()), 0.0762};
    look.tag = v.look.tag.value_or(tag);
  }
  look.tag_height_m = v.look.tag_height_m.value_or(v.params.body_height_m);
  look.tag_mount.yaw_deg = v.look.tag_yaw_deg.value_or(0.0);
  look.tag_mount.ahead_m = v.look.tag_ahead_m.value_or(v.params.body_centre_ahead_of_rear_axle_m);
  look.tag_mount.left_m = v.look.tag_left_m.value_or(0.0);
  return look;
}

namespace {

// The cars' roof tag mountings from the city's `eye` section (one declaration for the Eye and
// the simulator): each car the Eye lists gets its entry's mounting; a car that also gives one
// in its `look` is refused.
void TakeEyeMountings(const std::string& path, const YAML::Node& root, SimConfig& sim) {
  const std::vector<camera::DeclaredRoofTagMount> declared = camera::LoadCityRoofTagMounts(path);
  for (std::size_t i = 0; i < sim.vehicles.size(); ++i) {
    VehicleLookConfig& look = sim.vehicles[i].look;
    for (const camera::DeclaredRoofTagMount& d : declared) {
      if (d.vehicle != sim.vehicles[i].name) continue;
      if (look.mounts_tag()) {
        const YAML::Node node = root["sim"]["vehicles"][i]["look"];
        throw ConfigError(path + ":" + std::to_string(node.Mark().line + 1) + ": sim.vehicles[" +
                          std::to_string(i) + "].look: " + d.vehicle +
                          "'s roof tag mounting (tag_yaw_deg, tag_ahead_m, tag_left_m) is "
                          "declared by the Eye's entry too (" +
                          d.where +
                          "); declare it once, there: the simulator draws the tag where the Eye "
                          "expects it");
      }
      look.tag_yaw_deg = d.mount.yaw_deg;
      look.tag_ahead_m = d.mount.ahead_m;
      look.tag_left_m = d.mount.left_m;
    }
  }
}

}  // namespace

namespace {

// The `districts:` section of a city file, alone of its top-level keys.
struct DistrictsSection {
  std::vector<maps::DistrictConfig> districts;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("districts", districts);
  }
};

}  // namespace

SimCity LoadSimCity(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw ConfigError(path + ": cannot read the city file");
  } catch (const YAML::Exception& e) {
    throw ConfigError(path + ":" + std::to_string(e.mark.line + 1) + ":" +
                      std::to_string(e.mark.column + 1) + ": YAML syntax error (" + e.msg + ")");
  }
  const auto text = [&](const char* key) {
    const YAML::Node n = root.IsMap() ? root[key] : YAML::Node();
    if (!n || !n.IsScalar()) {
      throw ConfigError(path + ": " + key + ": missing or not a string (the city file's " + key +
                        ")");
    }
    return n.as<std::string>();
  };
  SimCity city;
  city.name = text("name");
  std::filesystem::path map = text("map");
  if (map.is_relative()) map = std::filesystem::path(path).parent_path() / map;
  city.map_path = map.lexically_normal().string();
  if (root["sim"]) city.sim = config::LoadFile<SimConfig>(path, "sim");
  if (const YAML::Node districts = root["districts"]) {
    // Checked with its lines by the SCM and `autodrive-city check`; read here alone.
    YAML::Emitter out;
    out << YAML::BeginMap << YAML::Key << "districts" << YAML::Value << districts << YAML::EndMap;
    city.districts =
        config::LoadString<DistrictsSection>(out.c_str(), path + " (its districts: section)")
            .districts;
  }
  TakeEyeMountings(path, root, city.sim);
  const auto resolve = [&](LensConfig& lens) {
    if (!lens.calibration) return;
    std::filesystem::path file = *lens.calibration;
    if (file.is_relative()) file = std::filesystem::path(path).parent_path() / file;
    lens.calibration = file.lexically_normal().string();
  };
  for (auto& v : city.sim.vehicles) {
    resolve(v.sensors.front_camera.lens);
    resolve(v.sensors.rear_camera.lens);
  }
  for (auto& c : city.sim.cameras) resolve(c.lens);
  return city;
}

std::vector<RigidTransform2> SpawnPoses(const SimConfig& sim, const maps::Map& map) {
  std::vector<RigidTransform2> poses;
  std::set<std::pair<int, int>> used_tiles;
  std::set<std::uint32_t> used_lanes;
  const auto pose_on = [&](const maps::Lane& lane, double along, const std::string& car) {
    const maps::Polyline& c = lane.centreline;
    AUTODRIVE_THROW_UNLESS(c.size() >= 2, car << ": lane " << lane.name << " has no centreline");
    AUTODRIVE_THROW_UNLESS(along <= maps::PolylineLength(c) + 1e-9,
                           car << ": along_m " << along << " is beyond the end of lane "
                               << lane.name << " (" << lane.length_m << " m)");
    const auto [p, yaw] = maps::PointAlong(c, along);
    return RigidTransform2(p, yaw);
  };
  for (const SimVehicleConfig& v : sim.vehicles) {
    if (v.spawn && v.spawn->lane) {
      const maps::Lane* found = nullptr;
      for (const maps::Lane& lane : map.lanes) {
        if (lane.name == *v.spawn->lane) found = &lane;
      }
      AUTODRIVE_THROW_UNLESS(found != nullptr, v.name << ": the map " << map.name
                                                      << " has no lane '" << *v.spawn->lane << "'");
      poses.push_back(pose_on(*found, v.spawn->along_m, v.name));
    } else if (v.spawn) {
      poses.push_back(RigidTransform2::FromXyYaw(*v.spawn->x_m, *v.spawn->y_m, *v.spawn->yaw_rad));
    } else {
      // The middle of a lane that no car took: first lanes on tiles no car took, then lanes
      // that no intersection starts or ends, then any lane long enough.
      const auto fits = [&](const maps::Lane& lane, int pass) {
        if (used_lanes.count(lane.id.value()) > 0 || lane.length_m < 0.3) return false;
        const bool open_road = !lane.ingress_of && !lane.egress_of;
        if (pass == 0) return open_road && used_tiles.count({lane.tile.row, lane.tile.col}) == 0;
        if (pass == 1) return open_road;
        return true;
      };
      const maps::Lane* found = nullptr;
      for (int pass = 0; pass < 3 && found == nullptr; ++pass) {
        for (const maps::Lane& lane : map.lanes) {
          if (fits(lane, pass)) {
            found = &lane;
            break;
          }
        }
      }
      AUTODRIVE_THROW_UNLESS(found != nullptr, v.name << ": no free lane left on map " << map.name
                                                      << " to start on; give it a spawn");
      const maps::Lane& lane = *found;
      used_lanes.insert(lane.id.value());
      used_tiles.insert({lane.tile.row, lane.tile.col});
      poses.push_back(pose_on(lane, lane.length_m / 2, v.name));
    }
  }
  const double position_sigma = sim.variability.StartPositionNoiseM();
  const double heading_sigma = sim.variability.StartHeadingNoiseRad();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    std::mt19937_64 rng(StreamSeed(sim.seed, static_cast<int>(i), kStartStream));
    const double dx = Gaussian(rng, position_sigma);
    const double dy = Gaussian(rng, position_sigma);
    const double dyaw = Gaussian(rng, heading_sigma);
    const Eigen::Vector2d p = poses[i].translation();
    poses[i] = RigidTransform2::FromXyYaw(p.x() + dx, p.y() + dy, poses[i].yaw() + dyaw);
  }
  return poses;
}

// ---------------------------------------------------------------------------------------------
// Checks of configuration types declared with their users (sensors.h, raycast.h), kept here with
// the loader so that a city's simulator section loads without the simulator (the launcher and
// the dashboard link autodrive::vehicle_sim_config alone).

void LidarConfig::Validate() const {
  AUTODRIVE_THROW_UNLESS(range_min_m < range_max_m, "range_min_m " << range_min_m
                                                                   << " must be below range_max_m "
                                                                   << range_max_m);
}

void StaticSceneOptions::Validate() const {
  const auto check = [](double v, double lo, double hi, const char* name) {
    AUTODRIVE_THROW_UNLESS(v >= lo && v <= hi, "StaticSceneOptions: " << name << " must be in ["
                                                                      << lo << ", " << hi
                                                                      << "], got " << v);
  };
  check(cell_size_m, 0.01, 10.0, "cell_size_m");
  check(pole_radius_m, 0.001, 1.0, "pole_radius_m");
  check(signal_head_height_m, 0.0, 10.0, "signal_head_height_m");
  check(sign_height_m, 0.0, 10.0, "sign_height_m");
}

}  // namespace autodrive::vehicle_sim
