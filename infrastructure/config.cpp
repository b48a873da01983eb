#include "infrastructure/config.h"

#include <yaml-cpp/yaml.h>

#include <set>
#include <sstream>
#include <variant>

#include "common/error.h"
#include "maps/map_io.h"

namespace autodrive::infrastructure {
namespace {

// One step of a key path: a mapping key or a sequence index.
using PathStep = std::variant<std::string, std::size_t>;

// "heads[2]", "serial[0].head".
std::string KeyPath(const std::vector<PathStep>& steps) {
  std::string text;
  for (const auto& step : steps) {
    if (const auto* key = std::get_if<std::string>(&step)) {
      if (!text.empty()) text += '.';
      text += *key;
    } else {
      text += "[" + std::to_string(std::get<std::size_t>(step)) + "]";
    }
  }
  return text;
}

// Throws ConfigError "FILE:LINE:COLUMN: KEYPATH: message" for a value of the config file,
// found by reading the file again (the struct keeps no positions). Without a position (the
// key is absent: a default is at fault) the message is "FILE: KEYPATH: message".
[[noreturn]] void FailAt(const std::filesystem::path& file, const std::vector<PathStep>& steps,
                         const std::string& message) {
  std::string where = file.string();
  try {
    YAML::Node node = YAML::LoadFile(file.string());
    bool found = true;
    for (const auto& step : steps) {
      if (const auto* key = std::get_if<std::string>(&step)) {
        found = node.IsMap() && node[*key].IsDefined();
        if (found) node = node[*key];
      } else {
        const std::size_t index = std::get<std::size_t>(step);
        found = node.IsSequence() && index < node.size();
        if (found) node = node[index];
      }
      if (!found) break;
    }
    if (found) {
      const YAML::Mark mark = node.Mark();
      where += ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
    }
  } catch (const YAML::Exception&) {
    // The file was loaded a moment ago; if it changed since, report without a position.
  }
  throw ConfigError(where + ": " + KeyPath(steps) + ": " + message);
}

std::string JoinIds(const std::vector<SignalHeadId>& ids) {
  std::ostringstream out;
  for (std::size_t i = 0; i < ids.size(); ++i) out << (i ? ", " : "") << ids[i].value();
  return out.str();
}

}  // namespace

bool InfraConfig::IsValidName(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}

bool InfraConfig::AllDistinct(const std::vector<std::uint32_t>& ids) {
  return std::set<std::uint32_t>(ids.begin(), ids.end()).size() == ids.size();
}

bool InfraConfig::SerialEntriesDistinct(const std::vector<SerialHeadConfig>& entries) {
  std::set<std::uint32_t> heads;
  std::set<std::string> ports;
  for (const auto& e : entries) {
    if (!heads.insert(e.head).second || !ports.insert(e.port).second) return false;
  }
  return true;
}

void InfraConfig::Validate() const {
  if (heads.empty()) return;
  for (std::size_t i = 0; i < serial.size(); ++i) {
    AUTODRIVE_THROW_UNLESS(std::find(heads.begin(), heads.end(), serial[i].head) != heads.end(),
                           "serial[" << i << "].head: head " << serial[i].head
                                     << " is not one of the hosted heads (heads)");
  }
}

InfraConfig LoadInfraConfig(const std::filesystem::path& path) {
  return config::LoadFile<InfraConfig>(path);
}

HostPlan PlanHost(const InfraConfig& config, const std::filesystem::path& config_file) {
  HostPlan plan;
  std::filesystem::path map_path(config.map);
  if (map_path.is_relative()) map_path = config_file.parent_path() / map_path;
  try {
    plan.map = maps::LoadMapOrLayout(map_path.string());
  } catch (const InputError& e) {
    FailAt(config_file, {"map"},
           "cannot load the map " + map_path.string() + " (" + e.what() + ")");
  }
  const maps::Map& map = plan.map;
  std::vector<SignalHeadId> all;
  for (const auto& h : map.signal_heads) all.push_back(h.id);
  const auto find_head = [&](std::uint32_t id) -> const maps::SignalHead* {
    return map.HasSignalHead(SignalHeadId(id)) ? &map.signal_head(SignalHeadId(id)) : nullptr;
  };
  const std::string known = all.empty() ? "it has none" : "it has " + JoinIds(all);

  std::vector<std::uint32_t> hosted = config.heads;
  if (hosted.empty()) {
    if (all.empty()) {
      FailAt(config_file, {"map"},
             "map " + map.name + " has no signal heads (no intersection with control=signal)");
    }
    for (const auto id : all) hosted.push_back(id.value());
  }
  for (std::size_t i = 0; i < config.heads.size(); ++i) {
    if (find_head(config.heads[i]) == nullptr) {
      FailAt(config_file, {"heads", i},
             "no signal head " + std::to_string(config.heads[i]) + " in map " + map.name + " (" +
                 known + ")");
    }
  }
  for (std::size_t i = 0; i < config.serial.size(); ++i) {
    if (find_head(config.serial[i].head) == nullptr) {
      FailAt(config_file, {"serial", i, "head"},
             "no signal head " + std::to_string(config.serial[i].head) + " in map " + map.name +
                 " (" + known + ")");
    }
  }
  std::sort(hosted.begin(), hosted.end());
  for (const auto id : hosted) {
    const maps::SignalHead& head = *find_head(id);
    HeadPlan h;
    h.id = head.id;
    h.intersection = head.intersection;
    h.backend = config.default_backend;
    for (const auto& s : config.serial) {
      if (s.head == id) {
        h.backend = BackendType::kSerial;
        h.serial = s;
      }
    }
    if (h.backend == BackendType::kSerial && !h.serial) {
      FailAt(config_file, {"default_backend"},
             "head " + std::to_string(id) +
                 " would use the serial backend but has no entry in serial (add {head: " +
                 std::to_string(id) + ", port: ...})");
    }
    plan.heads.push_back(std::move(h));
  }
  return plan;
}

}  // namespace autodrive::infrastructure
