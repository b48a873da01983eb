#include "vehicle_sim/camera_config.h"

#include <cstdio>

#include "common/error.h"

namespace autodrive::vehicle_sim {

namespace {

int HexDigit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

Rgb Rgb::FromConfigString(std::string_view text) {
  bool ok = text.size() == 7 && text[0] == '#';
  std::array<int, 6> d{};
  for (std::size_t k = 0; ok && k < 6; ++k) {
    d[k] = HexDigit(text[k + 1]);
    ok = d[k] >= 0;
  }
  AUTODRIVE_THROW_UNLESS(ok, "a colour is \"#rrggbb\" (hexadecimal), got \"" << text << "\"");
  return {static_cast<std::uint8_t>(d[0] * 16 + d[1]), static_cast<std::uint8_t>(d[2] * 16 + d[3]),
          static_cast<std::uint8_t>(d[4] * 16 + d[5])};
}

std::string Rgb::ToConfigString() const {
  char text[8];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", r, g, b);
  return text;
}

bool FilmOptions::AnyEffect() const {
  return exposure != 1.0 || exposure_time_s > 0.0 || blur_sigma_px > 0.0 || noise_sigma > 0.0;
}

void LensConfig::Validate() const {
  const bool figures = width_px || height_px || focal_length_mm || sensor_width_mm || distortion;
  AUTODRIVE_THROW_UNLESS(!(calibration && figures),
                         "give a lens either a calibration file or its figures (width_px, "
                         "height_px, focal_length_mm, sensor_width_mm, distortion), not both");
  AUTODRIVE_THROW_UNLESS(!calibration || !calibration->empty(), "calibration: an empty path");
  if (distortion) {
    const std::size_t n = distortion->size();
    AUTODRIVE_THROW_UNLESS(n == 0 || n == 4 || n == 5 || n == 8,
                           "distortion: 0, 4, 5 or 8 coefficients (OpenCV's k1 k2 p1 p2 [k3 "
                           "[k4 k5 k6]]), got "
                               << n);
  }
}

camera::Intrinsics LensConfig::Intrinsics() const {
  if (calibration) return camera::LoadOpenCvCalibration(*calibration);
  camera::Intrinsics k =
      camera::IntrinsicsFromSensor(focal_length_mm.value_or(camera::kPiCameraV21FocalLengthMm),
                                   sensor_width_mm.value_or(camera::kPiCameraV21SensorWidthMm),
                                   width_px.value_or(1280), height_px.value_or(720));
  if (distortion) k.distortion = *distortion;
  k.Validate();
  return k;
}

Eigen::Isometry3d MountConfig::OpticalPose() const {
  return camera::CameraPoseFromMount({x_m, y_m, z_m}, {roll_rad, pitch_rad, yaw_rad});
}

OnboardCameraConfig DefaultFrontCamera() {
  OnboardCameraConfig c;
  c.mount = {0.195, 0.0, 0.110, 0.0, 7.3 * kPi / 180, 0.0};
  return c;
}

OnboardCameraConfig DefaultRearCamera() {
  OnboardCameraConfig c;
  c.mount = {-0.035, 0.0, 0.110, 0.0, 7.3 * kPi / 180, kPi};
  return c;
}

void OverheadCameraConfig::Validate() const {
  bool ok = !name.empty() && name.size() <= 64 && name[0] >= 'a' && name[0] <= 'z';
  for (const char c : name) {
    ok = ok && ((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_');
  }
  AUTODRIVE_THROW_UNLESS(
      ok, "name: a camera's name is [a-z][a-z0-9_]* (at most 64), got \"" << name << "\"");
  AUTODRIVE_THROW_UNLESS(!lost_until_s || (lost_from_s && *lost_until_s > *lost_from_s),
                         "lost_until_s needs lost_from_s before it");
}

camera::Intrinsics OverheadCameraConfig::Intrinsics() const {
  if (lens.calibration || lens.width_px || lens.height_px) return lens.Intrinsics();
  LensConfig full_hd = lens;
  full_hd.width_px = 1920;
  full_hd.height_px = 1080;
  return full_hd.Intrinsics();
}

}  // namespace autodrive::vehicle_sim
