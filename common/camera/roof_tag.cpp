#include "common/camera/roof_tag.h"

#include <cmath>

namespace autodrive::camera {

double RoofTagMount::yaw_VT_rad() const { return yaw_deg * kPi / 180.0 - kPi / 2; }

double RoofTagMount::VehicleYaw(double tag_yaw_M_rad) const {
  return WrapAngle(tag_yaw_M_rad - yaw_VT_rad());
}

double RoofTagMount::TagYaw(double vehicle_yaw_M_rad) const {
  return WrapAngle(vehicle_yaw_M_rad + yaw_VT_rad());
}

RigidTransform2 RoofTagMount::X_VT() const { return RigidTransform2(p_VT(), yaw_VT_rad()); }

namespace {

// A car's entry as far as the mounting goes: its name and the mounting's keys.
struct MountEntry {
  std::string name;
  RoofTagMount mount;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    mount.Serialize(a);
  }
};

}  // namespace

std::vector<DeclaredRoofTagMount> LoadCityRoofTagMounts(const std::filesystem::path& city_file) {
  namespace ci = config::internal;
  const std::string file = city_file.string();
  const ci::Document document = ci::ParseDocument(config::ReadFile(city_file), file, "");
  std::vector<DeclaredRoofTagMount> out;
  // A section that is not there or not of the right shape declares nothing here: the Eye's
  // own loader refuses it with its position.
  if (!document.root.IsMap()) return out;
  const auto eye = ci::FindKey(document.root, "eye");
  if (!eye || !eye->value.IsMap()) return out;
  const auto vehicles = ci::FindKey(eye->value, "vehicles");
  if (!vehicles || !vehicles->value.IsSequence()) return out;
  for (std::size_t i = 0; i < vehicles->value.size(); ++i) {
    const YAML::Node entry = vehicles->value[i];
    const ci::Loc loc{&file, entry.Mark(), ci::JoinIndex("eye.vehicles", i)};
    // Only the keys named here are read; the Eye checks that there are no others.
    ci::CheckMappingKeys(entry, loc, /*allowed=*/nullptr);
    MountEntry read;
    ci::Reader reader(entry, loc);
    read.Serialize(reader);
    out.push_back({read.name, read.mount,
                   file + ":" + std::to_string(entry.Mark().line + 1) + ": " + loc.path});
  }
  return out;
}

}  // namespace autodrive::camera
