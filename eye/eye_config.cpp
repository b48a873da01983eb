#include "eye/eye_config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <set>

#include "common/camera/tag_family.h"
#include "common/error.h"

namespace autodrive::eye {

namespace {

const char* const kSchemes[] = {"topic:", "device:", "video:", "url:", "images:"};

bool PlainWord(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
  });
}

}  // namespace

void DetectorConfig::Validate() const {
  const std::vector<std::string> names = camera::TagFamily::Names();
  if (std::find(names.begin(), names.end(), family) == names.end()) {
    std::string known;
    for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
    throw InputError("family: unknown AprilTag family \"" + family + "\" (known: " + known + ")");
  }
}

void VehicleTagConfig::Validate() const { (void)ParseVehicleName(name); }

VehicleId VehicleTagConfig::id() const { return ParseVehicleName(name); }

void CameraConfig::Validate() const {
  if (!PlainWord(name)) {
    throw InputError(
        "name: a camera's name must be a plain word (letters, digits, _ and -), got \"" + name +
        "\"");
  }
  bool known = false;
  for (const char* scheme : kSchemes) {
    const std::string s(scheme);
    if (source.rfind(s, 0) == 0 && source.size() > s.size()) known = true;
  }
  if (!known) {
    throw InputError(
        "source: expected topic:NAME, device:N or device:/dev/videoN, video:FILE, "
        "url:URL or images:DIR, got \"" +
        source + "\"");
  }
}

void EyeConfig::Validate() const {
  if (cameras.empty()) throw InputError("cameras: at least one camera is needed");
  std::set<std::string> camera_names;
  for (const CameraConfig& c : cameras) {
    if (!camera_names.insert(c.name).second) {
      throw InputError("cameras: the name \"" + c.name + "\" is used twice");
    }
  }
  const camera::TagFamily family(detector.family);
  std::set<std::string> vehicle_names;
  std::set<int> ids;
  for (const VehicleTagConfig& v : vehicles) {
    if (!vehicle_names.insert(v.name).second) {
      throw InputError("vehicles: " + v.name + " is listed twice");
    }
    family.CheckId(v.tag_id);
    if (!ids.insert(v.tag_id).second) {
      throw InputError("vehicles: " + v.name + "'s tag_id " + std::to_string(v.tag_id) +
                       " is another tag's too");
    }
  }
  for (const ReferenceTagConfig& r : reference_tags) {
    family.CheckId(r.id);
    if (!ids.insert(r.id).second) {
      throw InputError("reference_tags: the id " + std::to_string(r.id) +
                       " is another tag's too (a car's or another reference tag's)");
    }
  }
}

EyeConfig LoadEyeConfig(const std::filesystem::path& path) {
  // A city file has `name` and `map` at its top; then the Eye's part is its `eye` section.
  bool city = false;
  try {
    const YAML::Node root = YAML::LoadFile(path.string());
    city = root.IsMap() && root["name"] && root["map"];
  } catch (const YAML::BadFile&) {
    throw ConfigError(path.string() + ": cannot read the Eye's configuration");
  } catch (const YAML::Exception&) {
    // Let the strict loader report the syntax error with its position.
  }
  EyeConfig config = config::LoadFile<EyeConfig>(path, city ? "eye" : "");
  const std::filesystem::path folder = path.parent_path();
  const auto resolve = [&](std::string& file) {
    std::filesystem::path p = file;
    if (p.is_relative()) p = folder / p;
    file = p.lexically_normal().string();
  };
  for (CameraConfig& c : config.cameras) {
    resolve(c.calibration);
    if (c.pose) resolve(*c.pose);
    for (const char* scheme : {"video:", "images:"}) {
      const std::string s(scheme);
      if (c.source.rfind(s, 0) == 0) {
        std::string rest = c.source.substr(s.size());
        resolve(rest);
        c.source = s + rest;
      }
    }
  }
  return config;
}

}  // namespace autodrive::eye
