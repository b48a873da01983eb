#pragma once
/// @file
/// A pinhole camera with OpenCV's lens distortion model, shared by the simulator (which renders
/// images through it) and the Eye (which detects AprilTags and calibrates with it).
///
/// Frames (see docs/camera.md):
/// - The **optical frame** C is OpenCV's: origin at the centre of projection, x right in the
///   image, y down in the image, z forward along the optical axis. `Project` and `Unproject`
///   work in it.
/// - The **camera body frame** B is ROS REP 103's: same origin, x forward (along the optical
///   axis), y left, z up (towards the top of the image). A mount is given as the pose of B in a
///   parent frame P (the car's body frame, X forward, Y left, Z up, or the map frame, X east,
///   Y north, Z up) by position and roll-pitch-yaw in ROS's convention (common/geometry.h):
///   with all angles zero the camera looks along P's +x with the image's top towards P's +z;
///   positive pitch tilts it down, positive yaw turns it left (counter-clockwise seen from
///   above). Straight down is pitch = +90°.
/// - Pixels follow OpenCV: (u, v) = (column, row), the centre of the top-left pixel is (0, 0)
///   and the image spans [-0.5, width - 0.5] x [-0.5, height - 0.5].
///
/// The distortion model is OpenCV's (calib3d "Detailed description"), with coefficients in
/// OpenCV's order k1, k2, p1, p2[, k3[, k4, k5, k6]]: for a point (X, Y, Z) in C with Z > 0,
/// x = X/Z, y = Y/Z, r^2 = x^2 + y^2,
///
///     x'' = x * (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
///             + 2 p1 x y + p2 (r^2 + 2 x^2)
///     y'' = y * (1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)
///             + p1 (r^2 + 2 y^2) + 2 p2 x y
///     u = fx x'' + cx,  v = fy y'' + cy.
///
/// Units: pixels (`_px`), metres (`_m`), radians (`_rad`); normalised image coordinates
/// (x = X/Z, y = Y/Z) have none.

#include <array>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/geometry.h"

namespace cv {
class FileStorage;
}  // namespace cv

namespace autodrive::camera {

/// Points nearer the image plane than this depth (metres along the optical axis, z in the
/// optical frame) are not projected: `Project` returns `std::nullopt` for z <= kMinDepthM.
inline constexpr double kMinDepthM = 1e-6;

/// The largest angle between a ray and the optical axis that the model accepts, radians
/// (89.9°): beyond it `Project` returns `std::nullopt` whatever the distortion.
inline constexpr double kMaxRayAngleRad = 89.9 * kPi / 180.0;

/// What a camera is inside: image size, focal lengths, principal point and lens distortion, as
/// OpenCV's camera matrix and distortion vector hold them. A plain value; `Validate` checks it.
struct Intrinsics {
  int width_px = 0;    ///< Image width, pixels; > 0.
  int height_px = 0;   ///< Image height, pixels; > 0.
  double fx_px = 0.0;  ///< Focal length along x (columns), pixels; > 0.
  double fy_px = 0.0;  ///< Focal length along y (rows), pixels; > 0.
  double cx_px = 0.0;  ///< Principal point, column, pixels (OpenCV convention, see file).
  double cy_px = 0.0;  ///< Principal point, row, pixels.
  /// Distortion coefficients in OpenCV's order k1, k2, p1, p2, k3, k4, k5, k6: empty (no
  /// distortion), 4 (k3 = 0), 5, or 8 (rational model). OpenCV's 12- and 14-coefficient models
  /// (thin prism, tilted sensor) are not supported.
  std::vector<double> distortion;

  /// Throws `InputError` naming the field and the value seen when a size or focal length is not
  /// positive, a value is not finite, or `distortion` does not have 0, 4, 5 or 8 elements.
  void Validate() const;

  /// OpenCV's camera matrix `[fx 0 cx; 0 fy cy; 0 0 1]`.
  [[nodiscard]] Eigen::Matrix3d CameraMatrix() const;

  /// `distortion` padded with zeros to the eight coefficients k1, k2, p1, p2, k3, k4, k5, k6.
  /// Precondition: `distortion.size() <= 8`.
  [[nodiscard]] std::array<double, 8> DistortionCoefficients() const;

  /// Field-by-field equality (exact).
  bool operator==(const Intrinsics&) const = default;
};

/// Intrinsics of an ideal pinhole camera from its physical figures: square pixels,
/// fx = fy = focal_length_mm * width_px / sensor_width_mm, principal point at the centre of the
/// image, ((width_px - 1) / 2, (height_px - 1) / 2) in OpenCV's pixel convention (so the
/// optical axis goes through the middle of the sensor and the field of view is symmetric), no
/// distortion. The sensor width is that of the part of the sensor the image covers.
/// @throws InputError if a figure is not finite and positive.
[[nodiscard]] Intrinsics IntrinsicsFromSensor(double focal_length_mm, double sensor_width_mm,
                                              int width_px, int height_px);

/// The Raspberry Pi Camera Module V2.1 (Sony IMX219): focal length 3.04 mm.
inline constexpr double kPiCameraV21FocalLengthMm = 3.04;
/// The IMX219's active area width, mm (3280 pixels of 1.12 µm).
inline constexpr double kPiCameraV21SensorWidthMm = 3.68;

/// Nigel's cameras: a PiCamera V2.1 at 1280 x 720 over the sensor's full width,
/// `IntrinsicsFromSensor(3.04, 3.68, 1280, 720)`: fx = fy = 1057.39 px, principal point
/// (639.5, 359.5), no distortion; horizontal field of view 2 atan(3.68 / 2 / 3.04) = 62.37°
/// (the Raspberry Pi documentation quotes 62.2° beside these figures), vertical
/// 2 atan(360 / 1057.39) = 37.60° (the 16:9 image uses the middle 2.07 mm of the 2.76 mm high
/// sensor).
[[nodiscard]] Intrinsics PiCameraV21Intrinsics();

/// Horizontal and vertical field of view, radians.
struct FieldOfView {
  double horizontal_rad = 0.0;  ///< Angle between the rays through the left and right edges.
  double vertical_rad = 0.0;    ///< Angle between the rays through the top and bottom edges.
};

/// The camera model: validated intrinsics with projection and unprojection. Immutable after
/// construction; copyable and movable; every member may be called from any thread.
///
/// Valid region: OpenCV's polynomial distortion stops being one-to-one beyond some radius (a
/// lens with k1 = -0.5 and nothing else folds at r = 0.816, and points further out would land
/// back inside the image). The constructor finds the normalised radius `max_normalized_radius`
/// up to which the radial distortion r * (1 + k1 r^2 + ...) / (1 + k4 r^2 + ...) strictly
/// increases and its denominator stays positive (sampled every 0.01° of ray angle up to
/// kMaxRayAngleRad, then bisected); `Project` refuses points beyond it and `Unproject` returns
/// only rays within it. For real lenses the radius lies outside the image.
class CameraModel {
 public:
  /// @throws InputError (from `Intrinsics::Validate`) if `intrinsics` is not valid.
  explicit CameraModel(Intrinsics intrinsics);

  /// The intrinsics this model was built from.
  [[nodiscard]] const Intrinsics& intrinsics() const { return intrinsics_; }

  /// The normalised radius sqrt(x^2 + y^2) (x = X/Z, y = Y/Z) up to which the distortion is
  /// one-to-one; at most tan(kMaxRayAngleRad). See the class comment.
  [[nodiscard]] double max_normalized_radius() const { return max_radius_; }

  /// The pixel (u, v) where the point `p_CQ` (metres, in the optical frame C) appears, with
  /// distortion; it may lie outside the image. Agrees with `cv::projectPoints` (identity pose).
  /// `std::nullopt` when the point is not in front of the camera (z <= kMinDepthM) or outside
  /// the valid region (see the class comment).
  /// @throws InputError if a coordinate is not finite.
  [[nodiscard]] std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_CQ) const;

  /// The distorted normalised coordinates (x'', y'') of undistorted ones (x, y) = (X/Z, Y/Z):
  /// the distortion formula of the file comment, without the camera matrix. Applied to any
  /// finite input (no valid-region check).
  [[nodiscard]] Eigen::Vector2d Distort(const Eigen::Vector2d& xy) const;

  /// The undistorted normalised coordinates (x, y) = (X/Z, Y/Z) of the ray seen at `pixel`
  /// (u, v): the inverse of `Project` up to depth, what `cv::undistortPoints` computes (which
  /// by default stops after 5 fixed-point iterations; this is exact).
  ///
  /// Method: Newton's method on the 2-D distortion map, with its analytic Jacobian, starting at
  /// the distorted coordinates and halving a step that would not reduce the residual or would
  /// leave the valid region; at most 20 iterations, stopping when the residual
  /// |Distort(x, y) - (x'', y'')| is at most 1e-15 * (1 + |(x'', y'')|) or a step no longer
  /// reduces it. The result is accepted when the residual is at most 1e-12 * (1 + |(x'', y'')|),
  /// which for real lenses (Jacobian near 1) is exact to about 1e-12 normalised units. Over
  /// the whole image of the lenses in the test (k1 = -0.28 and a rational model) Newton needs
  /// at most 4 iterations; near a fold, where the Jacobian vanishes, it needs more, hence 20.
  /// `std::nullopt` when no ray in the valid region is seen at `pixel` (beyond the fold of a
  /// strongly distorting model).
  /// @throws InputError if a coordinate is not finite.
  [[nodiscard]] std::optional<Eigen::Vector2d> UndistortToNormalized(
      const Eigen::Vector2d& pixel) const;

  /// The unit direction, in the optical frame, of the ray seen at `pixel`:
  /// (x, y, 1) / |(x, y, 1)| with (x, y) = `UndistortToNormalized(pixel)`. Every point on it
  /// projects back to `pixel`. For a rendered image, the ray of pixel (column i, row j) is
  /// `Unproject({i, j})` (pixel centres at integers). `std::nullopt` as for
  /// `UndistortToNormalized`.
  /// @throws InputError if a coordinate is not finite.
  [[nodiscard]] std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& pixel) const;

  /// True if `pixel` lies on the image: u in [-0.5, width - 0.5), v in [-0.5, height - 0.5).
  [[nodiscard]] bool IsInImage(const Eigen::Vector2d& pixel) const;

  /// The field of view, with distortion: horizontally the angle in the optical x-z plane
  /// between the rays through the middles of the left and right image edges, pixels
  /// (-0.5, cy) and (width - 0.5, cy); vertically, in the y-z plane, through (cx, -0.5) and
  /// (cx, height - 0.5). Without distortion and with the principal point at the centre, the
  /// horizontal one is 2 atan(width / 2 / fx).
  /// @throws InputError if an edge lies beyond the valid region (see the class comment).
  [[nodiscard]] FieldOfView fov() const;

 private:
  Intrinsics intrinsics_;
  std::array<double, 8> k_{};  // k1, k2, p1, p2, k3, k4, k5, k6
  double max_radius_ = 0.0;
};

/// The rotation `R_BC` of the optical frame C in the camera body frame B (x forward, y left,
/// z up): C's x (right) is B's -y, C's y (down) is B's -z, C's z (forward) is B's x. Its
/// columns are C's axes in B. (ROS's `camera_link` to `camera_optical_frame`, rpy
/// (-pi/2, 0, -pi/2).)
[[nodiscard]] Eigen::Matrix3d RotationBodyFromOptical();

/// The pose `X_PC` of the optical frame C in a parent frame P, for a camera whose body frame B
/// is at `p_PB_m` (metres, in P) with orientation `rpy_PB` (ROS convention, common/geometry.h:
/// R_PB = Rz(yaw) Ry(pitch) Rx(roll)): X_PC = X_PB * X_BC with X_BC = (RotationBodyFromOptical(),
/// 0). Examples: Nigel's front camera, `CameraPoseFromMount({0.195, 0, 0.110},
/// {.pitch_rad = 7.3 * kPi / 180})`; the rear one, `{.yaw_rad = kPi}`; a camera above the map
/// looking straight down with the image's top towards north (+y) and its right towards east
/// (+x), `{.pitch_rad = kPi / 2, .yaw_rad = kPi / 2}`.
/// @throws InputError if a value is not finite.
[[nodiscard]] Eigen::Isometry3d CameraPoseFromMount(const Eigen::Vector3d& p_PB_m,
                                                    const RollPitchYaw& rpy_PB);

/// A ray in some frame: its origin (metres) and unit direction.
struct Ray {
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();    ///< Start point, metres.
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< Unit direction.
};

/// A camera placed in the world: its model, the pose of its optical frame in a parent frame,
/// and names. A plain value, copyable and movable.
struct Camera {
  std::string name;             ///< Human name, e.g. "front".
  std::string frame_id;         ///< Id of the optical frame C, as images are stamped.
  std::string parent_frame_id;  ///< Id of the parent frame P that `X_PC` is expressed in.
  CameraModel model;            ///< Intrinsics, projection and unprojection.
  /// The pose of the optical frame C in the parent frame P (C to P: p_PQ = X_PC * p_CQ).
  /// See `CameraPoseFromMount`.
  Eigen::Isometry3d X_PC = Eigen::Isometry3d::Identity();

  /// The pixel where the point `p_PQ` (metres, in the parent frame) appears; `std::nullopt` as
  /// for `CameraModel::Project`.
  /// @throws InputError if a coordinate is not finite.
  [[nodiscard]] std::optional<Eigen::Vector2d> ProjectFromParent(const Eigen::Vector3d& p_PQ) const;

  /// The ray, in the parent frame, seen at `pixel`: from the camera's centre along the
  /// direction of `CameraModel::Unproject`. `std::nullopt` as for `Unproject`.
  /// @throws InputError if a coordinate is not finite.
  [[nodiscard]] std::optional<Ray> UnprojectToParent(const Eigen::Vector2d& pixel) const;
};

/// Reads a camera calibration file in the layout OpenCV's calibration samples write with
/// `cv::FileStorage` (YAML or XML): `image_width` and `image_height` (integers > 0),
/// `camera_matrix` (a 3x3 `!!opencv-matrix` `[fx 0 cx; 0 fy cy; 0 0 1]`, fx and fy > 0, no
/// skew) and `distortion_coefficients` (a 1xN or Nx1 `!!opencv-matrix`, N = 4, 5 or 8). Other
/// keys (calibration_time, flags, avg_reprojection_error, ...) are ignored. Values read back
/// exactly: OpenCV writes doubles with 17 significant digits.
/// @throws ConfigError whose message is `FILE: KEY: what was wrong (got ...)`, or
/// `FILE: cannot read ...` when the file is missing or cannot be parsed.
[[nodiscard]] Intrinsics LoadOpenCvCalibration(const std::filesystem::path& path);

/// Writes `intrinsics` in the layout `LoadOpenCvCalibration` reads (and OpenCV's tools read),
/// with `cv::FileStorage`; the format follows the extension (.yaml/.yml, .xml, .json). The
/// distortion is written as an Nx1 matrix of its coefficients, five zeros when it is empty.
/// Overwrites an existing file.
/// @throws InputError if `intrinsics` is not valid or the file cannot be written.
void SaveOpenCvCalibration(const std::filesystem::path& path, const Intrinsics& intrinsics);

/// As above; then `extra` writes further keys into the open file, after the four (a
/// calibration's board, errors and images, as OpenCV's own calibration sample writes them).
void SaveOpenCvCalibration(const std::filesystem::path& path, const Intrinsics& intrinsics,
                           const std::function<void(cv::FileStorage&)>& extra);

}  // namespace autodrive::camera
