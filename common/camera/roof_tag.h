#pragma once
/// @file
/// How a car's roof tag is mounted on the car: one definition for the simulator, which draws
/// the tag on its cars, and the Eye, which measures each car by its tag; and the reader of a
/// city file's declarations of it, so that one declaration (the Eye's `vehicles` entries)
/// serves both (docs/eye.md, "The roof tag's mounting").
///
/// Frames: a car's frame V (origin at the middle of its rear axle, x forward, y left, z up); a
/// tag's frame T (origin at the centre of its black square, x towards the bitmap's right edge,
/// y towards its top edge, z up out of the tag, which lies flat on the roof).
///
/// The picture, seen from above with the car's front up the page: the tag's centre lies
/// `tag_ahead_m` ahead of the middle of the rear axle and `tag_left_m` to its left, and the
/// tag's top edge (the top of its bitmap read upright) faces the car's front turned
/// `tag_yaw_deg` counter-clockwise. So at 0 (the default) the tag reads upright and the car
/// drives towards the tag's top; at 90 the top faces the car's left side and the car drives
/// towards the bitmap's right edge (T's +x); at 180 the tag is upside down; at 270 (or −90)
/// the top faces the car's right and the car drives towards the bitmap's left edge. In angles:
/// T's yaw in V (from V's x to T's x) is `tag_yaw_deg` − 90°, so the car's heading in the map
/// is the tag's yaw in the map + 90° − `tag_yaw_deg`.

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/config.h"
#include "common/geometry.h"

namespace autodrive::camera {

/// Where a car's roof tag sits on the car and which way it is turned (see the file comment).
/// A plain value.
struct RoofTagMount {
  /// The angle from the car's forward axis to the tag's top, counter-clockwise seen from
  /// above, degrees. 0: the tag's top towards the car's front (the default).
  double yaw_deg = 0.0;
  /// The tag's centre ahead of the middle of the rear axle, along V's x, metres. The default
  /// is the middle of Nigel's body (`body_centre_ahead_of_rear_axle_m`).
  double ahead_m = 0.07077;
  /// The tag's centre to the left of the car's centre line, along V's y, metres.
  double left_m = 0.0;

  static constexpr config::Range<double> kYawRangeDeg{-360.0, 360.0};
  static constexpr config::Range<double> kOffsetRangeM{-5.0, 5.0};

  /// The keys `tag_yaw_deg`, `tag_ahead_m` and `tag_left_m`, in the mapping of the struct
  /// that holds the mount (a car's entry), not a mapping of their own.
  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("tag_yaw_deg", yaw_deg, kYawRangeDeg);
    a.Optional("tag_ahead_m", ahead_m, kOffsetRangeM);
    a.Optional("tag_left_m", left_m, kOffsetRangeM);
  }

  /// T's yaw in V: the angle from V's x to T's x, radians (`yaw_deg` − 90°).
  [[nodiscard]] double yaw_VT_rad() const;
  /// The tag's centre in V (on the roof's plane), metres.
  [[nodiscard]] Eigen::Vector2d p_VT() const { return {ahead_m, left_m}; }
  /// The car's heading in the map (from M's x to V's x, in (−π, π]) whose tag has the yaw
  /// `tag_yaw_M_rad` in the map (from M's x to T's x).
  [[nodiscard]] double VehicleYaw(double tag_yaw_M_rad) const;
  /// The tag's yaw in the map (from M's x to T's x, in (−π, π]) of a car heading
  /// `vehicle_yaw_M_rad`.
  [[nodiscard]] double TagYaw(double vehicle_yaw_M_rad) const;
  /// The tag's frame T in V on the roof's plane: its centre and yaw.
  [[nodiscard]] RigidTransform2 X_VT() const;

  bool operator==(const RoofTagMount&) const = default;
};

/// A roof tag's mounting as a city file declares it for one car.
struct DeclaredRoofTagMount {
  std::string vehicle;  ///< the car's name
  RoofTagMount mount;
  /// Where: `FILE:LINE: eye.vehicles[I]`, for messages.
  std::string where;
};

/// The mountings a city file's `eye` section declares, one per entry of its `vehicles` (each
/// entry's `name` and its `tag_yaw_deg`, `tag_ahead_m` and `tag_left_m`, defaults for those
/// absent). The simulator reads them to draw each car's tag where the Eye expects it. The other
/// keys of the section are the Eye's and are not read here (`eye::LoadEyeConfig` checks them);
/// a file without an `eye` section, or whose section has no `vehicles` list, declares none.
/// @throws ConfigError naming the file, line and key for a bad or missing name or a mounting
/// value out of range, and for a file that cannot be read or parsed.
[[nodiscard]] std::vector<DeclaredRoofTagMount> LoadCityRoofTagMounts(
    const std::filesystem::path& city_file);

}  // namespace autodrive::camera
