#pragma once
/// @file
/// What the simulated cameras are, as a city file's `sim:` section gives them (every key is in
/// docs/vehicle_sim.md, "Cameras"): each car's `front_camera` and `rear_camera` (under its
/// `sensors`), the overhead cameras (`sim.cameras`), how each car looks (`look`: colour and
/// roof tag), the reference tags on the ground (`sim.ground_tags`) and the renderer's settings
/// (`sim.render`). The renderer (renderer.h) draws what these describe.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "common/camera/camera_model.h"
#include "common/camera/roof_tag.h"
#include "common/config.h"
#include "common/geometry.h"
#include "common/time.h"

namespace autodrive::vehicle_sim {

/// A colour, 8 bits per channel.
/// In a config: "#rrggbb" (hexadecimal, as in HTML).
struct Rgb {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  bool operator==(const Rgb&) const = default;
  /// @throws InputError for anything but "#" and six hexadecimal digits.
  static Rgb FromConfigString(std::string_view text);
  [[nodiscard]] std::string ToConfigString() const;
};

/// An AprilTag as printed: family, id and the edge of its black square (the size AprilTag's
/// pose estimation takes), metres. The tag is printed with its white border (one bit wide for
/// tag36h11) on a white plate exactly as big as the family's whole bitmap
/// (`total_width` bits: 10 for tag36h11, so a 76.2 mm tag sits on a 95.25 mm plate).
struct TagSpec {
  std::string family = "tag36h11";  ///< tag36h11, tag25h9, tag16h5, tagStandard41h12, ...
  int id = 0;
  double size_m = 0.0762;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("family", family);
    a.Required("id", id, config::Range{0, 100000});
    a.Optional("size_m", size_m, config::Range{0.001, 10.0});
  }
  bool operator==(const TagSpec&) const = default;
};

/// A tag fixed on the ground: a reference tag for the Eye's registration. Pose of its centre
/// and its yaw in the map frame: the tag's frame T has x towards the bitmap's right edge and y
/// towards its top edge (as the tag is seen from above, read upright), z up; yaw is the angle
/// from the map's x to T's x (so yaw 0 reads upright with its top to the north).
struct GroundTag {
  TagSpec tag;
  double x_m = 0.0;
  double y_m = 0.0;
  double yaw_rad = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("tag", tag);
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
  }
  bool operator==(const GroundTag&) const = default;
};

/// How a vehicle looks: its colour and its roof tag. The tag lies flat on the roof plate at
/// `tag_height_m` above the ground (the top of the car), placed and turned on the roof as
/// `tag_mount` says (common/camera/roof_tag.h): by default centred over the vehicle's body,
/// upright seen from above with its top towards the vehicle's front (the tag frame's y is the
/// vehicle's x and its x the vehicle's -y, so the vehicle's yaw is the tag's yaw plus 90°).
struct VehicleLook {
  Rgb colour{200, 30, 30};
  std::optional<TagSpec> tag;
  double tag_height_m = 0.257;
  camera::RoofTagMount tag_mount;

  bool operator==(const VehicleLook&) const = default;
};

/// The light and the film: per camera.
struct FilmOptions {
  double exposure = 1.0;  ///< gain on everything the camera sees, in (0, 20]
  /// Light: ambient share and one directional light (the lab's ceiling lights, as one sun),
  /// from `light_azimuth_rad` (counter-clockwise from east) and `light_elevation_rad` above the
  /// horizon. The ground in the default light shows its colours as the map's picture has them.
  double ambient = 0.6;
  double light_intensity = 0.4;
  double light_azimuth_rad = 0.8;
  double light_elevation_rad = 1.1;
  /// Motion blur: the frame integrates the light over this time, centred on the frame's
  /// instant (0: an instantaneous frame); vehicles move by their velocities, the camera by its
  /// own.
  double exposure_time_s = 0.0;
  int motion_blur_samples = 4;  ///< sub-frames averaged when exposure_time_s > 0, in [2, 32]
  double blur_sigma_px = 0.0;   ///< Gaussian blur (lens focus), pixels; 0: none
  double noise_sigma = 0.0;     ///< Gaussian noise, standard deviation in 8-bit levels; 0: none

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("exposure", exposure, config::Range{0.001, 20.0});
    a.Optional("ambient", ambient, config::Range{0.0, 10.0});
    a.Optional("light_intensity", light_intensity, config::Range{0.0, 10.0});
    a.Optional("light_azimuth_rad", light_azimuth_rad, config::Range{-10.0, 10.0});
    a.Optional("light_elevation_rad", light_elevation_rad, config::Range{0.0, 1.5708});
    a.Optional("exposure_time_s", exposure_time_s, config::Range{0.0, 1.0});
    a.Optional("motion_blur_samples", motion_blur_samples, config::Range{2, 32});
    a.Optional("blur_sigma_px", blur_sigma_px, config::Range{0.0, 50.0});
    a.Optional("noise_sigma", noise_sigma, config::Range{0.0, 32.0});
  }
  /// True when any effect beyond the light is on (motion blur, blur, noise) or the exposure is
  /// not 1.
  [[nodiscard]] bool AnyEffect() const;
  bool operator==(const FilmOptions&) const = default;
};

/// How a camera forms its image: from an OpenCV calibration file (`calibration`, resolved
/// against the city file's folder), or from the physical figures of an ideal pinhole (the
/// PiCamera V2.1 at 1280 x 720 by default: `camera::IntrinsicsFromSensor`) with an optional
/// OpenCV distortion vector. Not both.
struct LensConfig {
  std::optional<std::string> calibration;
  std::optional<int> width_px;
  std::optional<int> height_px;
  std::optional<double> focal_length_mm;
  std::optional<double> sensor_width_mm;
  std::optional<std::vector<double>> distortion;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("calibration", calibration);
    a.Optional("width_px", width_px, config::Range{16, 8192});
    a.Optional("height_px", height_px, config::Range{16, 8192});
    a.Optional("focal_length_mm", focal_length_mm, config::Range{0.1, 1000.0});
    a.Optional("sensor_width_mm", sensor_width_mm, config::Range{0.1, 1000.0});
    a.Optional("distortion", distortion, config::Range{-100.0, 100.0});
  }
  /// `calibration` or the figures, not both; a distortion of 0, 4, 5 or 8 coefficients.
  void Validate() const;
  /// The intrinsics: read from the calibration file, or made from the figures.
  /// @throws ConfigError naming the file for a bad calibration file.
  [[nodiscard]] camera::Intrinsics Intrinsics() const;
  bool operator==(const LensConfig&) const = default;
};

/// Where a camera is: its body frame (REP 103: x along the optical axis, y left, z up) in its
/// parent frame (the car's frame V for on-board cameras, the map frame for overhead ones), by
/// position and roll, pitch, yaw (common/camera: pitch +90 degrees looks straight down).
struct MountConfig {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rad = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("x_m", x_m, config::Range{-1e4, 1e4});
    a.Optional("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("z_m", z_m, config::Range{-1e4, 1e4});
    a.Optional("roll_rad", roll_rad, config::Range{-10.0, 10.0});
    a.Optional("pitch_rad", pitch_rad, config::Range{-10.0, 10.0});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
  }
  /// The pose of the camera's optical frame in the parent frame (`camera::CameraPoseFromMount`).
  [[nodiscard]] Eigen::Isometry3d OpticalPose() const;
  bool operator==(const MountConfig&) const = default;
};

/// Nigel's front and rear cameras (NIGEL.md: PiCamera V2.1 at 1280 x 720; front at
/// (0.195, 0, 0.110) m pitched 7.3 degrees down; rear at (-0.035, 0, 0.110) facing back, taken
/// with the same tilt). Off unless enabled: each costs a core's few milliseconds a frame.
struct OnboardCameraConfig {
  bool enabled = false;
  double rate_hz = 15.0;
  LensConfig lens;
  MountConfig mount;
  FilmOptions film;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("enabled", enabled);
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 240.0});
    a.Optional("lens", lens);
    a.Optional("mount", mount);
    a.Optional("film", film);
  }
  bool operator==(const OnboardCameraConfig&) const = default;
};
/// The defaults of the front and rear cameras' mounts.
[[nodiscard]] OnboardCameraConfig DefaultFrontCamera();
[[nodiscard]] OnboardCameraConfig DefaultRearCamera();

/// An overhead camera fixed in the lab: its image is published on
/// `/autodrive/cameras/<name>/image`. By default 1920 x 1080 (a 3.04 mm lens on a 3.68 mm wide
/// sensor scaled to 1920 pixels) 3 m above the map's origin looking straight down, image top to
/// the north; give its pose (`mount`, map frame) and lens.
struct OverheadCameraConfig {
  std::string name;  ///< [a-z][a-z0-9_]*: the topic's and frame's name
  double rate_hz = 30.0;
  LensConfig lens;
  MountConfig mount{0.0, 0.0, 3.0, 0.0, kPi / 2, kPi / 2};
  FilmOptions film;
  /// A camera lost for a while (its cable pulled, its computer down): no frame from
  /// `lost_from_s` until `lost_until_s` (simulated time; none: to the end).
  std::optional<Duration> lost_from_s;
  std::optional<Duration> lost_until_s;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 240.0});
    a.Optional("lens", lens);
    a.Optional("mount", mount);
    a.Optional("film", film);
    a.Optional("lost_from_s", lost_from_s,
               config::Range<Duration>{Duration{0}, std::chrono::hours(24 * 365)});
    a.Optional("lost_until_s", lost_until_s,
               config::Range<Duration>{Duration{0}, std::chrono::hours(24 * 365)});
  }
  /// The name is a valid topic segment; `lost_until_s` comes with `lost_from_s`, after it.
  void Validate() const;
  /// The lens's intrinsics, 1920 x 1080 unless the lens gives a size or a calibration.
  [[nodiscard]] camera::Intrinsics Intrinsics() const;
  bool operator==(const OverheadCameraConfig&) const = default;
};

/// How a car looks to the cameras: its body colour (by default a colour per car, in order:
/// red, blue, yellow, green, ...) and its roof tag (by default tag36h11, 76.2 mm, id n for
/// `nigel_<n>`; `roof_tag: false` for none) at `tag_height_m` (default: the body's height),
/// mounted as `tag_yaw_deg`, `tag_ahead_m` and `tag_left_m` say (common/camera/roof_tag.h;
/// defaults: upright, its top to the front, over the middle of the body). In a city file whose
/// `eye` section lists the car, the mounting is the Eye's entry's (`LoadSimCity`) and these
/// three keys are refused here: one declaration serves the simulator and the Eye.
struct VehicleLookConfig {
  std::optional<Rgb> colour;
  bool roof_tag = true;
  std::optional<TagSpec> tag;
  std::optional<double> tag_height_m;
  std::optional<double> tag_yaw_deg;
  std::optional<double> tag_ahead_m;  ///< default: `body_centre_ahead_of_rear_axle_m`
  std::optional<double> tag_left_m;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("colour", colour);
    a.Optional("roof_tag", roof_tag);
    a.Optional("tag", tag);
    a.Optional("tag_height_m", tag_height_m, config::Range{0.0, 10.0});
    a.Optional("tag_yaw_deg", tag_yaw_deg, camera::RoofTagMount::kYawRangeDeg);
    a.Optional("tag_ahead_m", tag_ahead_m, camera::RoofTagMount::kOffsetRangeM);
    a.Optional("tag_left_m", tag_left_m, camera::RoofTagMount::kOffsetRangeM);
  }
  /// Whether any of the mounting's keys is given.
  [[nodiscard]] bool mounts_tag() const {
    return tag_yaw_deg.has_value() || tag_ahead_m.has_value() || tag_left_m.has_value();
  }
  bool operator==(const VehicleLookConfig&) const = default;
};

/// The renderer's settings (`sim.render`).
struct RenderConfig {
  /// Size of a texel of the ground's picture (m): 2 mm, so a 5 m map is a 2500 px texture.
  double ground_texel_m = 0.002;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("ground_texel_m", ground_texel_m, config::Range{0.0005, 0.1});
  }
  bool operator==(const RenderConfig&) const = default;
};

}  // namespace autodrive::vehicle_sim
