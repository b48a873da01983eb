#include "traffic/traffic_config.h"

#include <yaml-cpp/yaml.h>

#include "common/error.h"

namespace autodrive::traffic {

TrafficConfig LoadTrafficConfig(const std::filesystem::path& path) {
  bool has_section = false;
  try {
    const YAML::Node root = YAML::LoadFile(path.string());
    has_section = root.IsMap() && root["traffic"];
  } catch (const YAML::BadFile&) {
    throw ConfigError(path.string() + ": cannot read the city file");
  } catch (const YAML::Exception&) {
    has_section = true;  // let the strict loader report the syntax error with its position
  }
  TrafficConfig config =
      has_section ? config::LoadFile<TrafficConfig>(path, "traffic") : TrafficConfig{};
  for (std::string& file : config.route_files) {
    std::filesystem::path p = file;
    if (p.is_relative()) p = path.parent_path() / p;
    file = p.lexically_normal().string();
  }
  return config;
}

}  // namespace autodrive::traffic
