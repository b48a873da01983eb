#pragma once
/// @file
/// The Eye's configuration: its cameras and where their frames come from, the AprilTag
/// detector, the cars' roof tags, the reference tags fixed on the ground, tracking and outputs.
/// A standalone file, or the `eye` section of a city file (docs/eye.md, "Configuration").
///
/// Frames: the map frame M (x east, y north, z up, metres); a car's frame V (origin at the
/// middle of its rear axle, x forward, y left, z up); a tag's frame T (origin at the centre of
/// its black square, x towards the bitmap's right edge, y towards its top edge, z up out of the
/// tag). A car's tag lies flat at `tag_height_m`, turned on the roof as its `mount` says
/// (by default its top towards the car's front: T's y is V's x, so the car's yaw is the tag's
/// yaw + 90°).

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/camera/roof_tag.h"
#include "common/config.h"
#include "common/ids.h"
#include "common/time.h"

namespace autodrive::eye {

/// The AprilTag detector's parameters (AprilTag 3's `apriltag_detector_t`) and the checks
/// against false positives.
struct DetectorConfig {
  std::string family = "tag36h11";  ///< tag36h11, tag25h9, tag16h5, tagStandard41h12, ...
  /// Quads are found on an image decimated by this (1 = full resolution). Decimation loses
  /// small tags: keep 1 for tags under about 30 px.
  double decimate = 1.0;
  double blur_sigma = 0.0;   ///< Gaussian blur before quad detection, px (0: none)
  bool refine_edges = true;  ///< snap the quad's edges to the image's gradients
  int max_hamming = 0;       ///< bit errors corrected (0: exact codes only; fewer false tags)
  /// Detections whose decision margin (the mean difference between a bit's intensity and the
  /// threshold) is below this are refused.
  double min_decision_margin = 20.0;
  double min_side_px = 8.0;  ///< quads with a side shorter than this are refused
  /// Quads whose opposite sides differ by more than this factor are refused (a square seen at
  /// up to about 60° from its normal passes).
  double max_side_ratio = 2.5;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("family", family);
    a.Optional("decimate", decimate, config::Range{1.0, 8.0});
    a.Optional("blur_sigma", blur_sigma, config::Range{0.0, 10.0});
    a.Optional("refine_edges", refine_edges);
    a.Optional("max_hamming", max_hamming, config::Range{0, 3});
    a.Optional("min_decision_margin", min_decision_margin, config::Range{0.0, 255.0});
    a.Optional("min_side_px", min_side_px, config::Range{3.0, 10000.0});
    a.Optional("max_side_ratio", max_side_ratio, config::Range{1.0, 100.0});
  }
  /// The family is one the library has. @throws InputError naming it and the known ones.
  void Validate() const;
  bool operator==(const DetectorConfig&) const = default;
};

/// A car and its roof tag: which tag, its size and height, and how it is mounted on the car
/// (`mount`: its yaw on the roof and its centre's place, keys `tag_yaw_deg`, `tag_ahead_m` and
/// `tag_left_m` in the car's entry; common/camera/roof_tag.h). In a city file these entries
/// are also where the simulator takes each car's mounting from (one declaration for both).
struct VehicleTagConfig {
  std::string name;             ///< `nigel_<n>`
  int tag_id = 0;               ///< in the detector's family
  double tag_size_m = 0.0762;   ///< side of the black square
  double tag_height_m = 0.257;  ///< the tag's plane above the ground (the car's top)
  /// The tag's yaw on the roof (0: its top towards the car's front) and its centre's place
  /// from the middle of the rear axle (default: 0.07077 m ahead, the middle of Nigel's body).
  camera::RoofTagMount mount;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("tag_id", tag_id, config::Range{0, 100000});
    a.Optional("tag_size_m", tag_size_m, config::Range{0.005, 5.0});
    a.Optional("tag_height_m", tag_height_m, config::Range{0.0, 10.0});
    mount.Serialize(a);  // tag_yaw_deg, tag_ahead_m, tag_left_m
  }
  /// @throws InputError if `name` is not `nigel_<n>`.
  void Validate() const;
  [[nodiscard]] VehicleId id() const;
  bool operator==(const VehicleTagConfig&) const = default;
};

/// A tag fixed on the ground at a known pose in the map: what registers the cameras.
struct ReferenceTagConfig {
  int id = 0;
  double size_m = 0.0762;
  double x_m = 0.0;  ///< its centre
  double y_m = 0.0;
  double z_m = 0.0;      ///< its plane's height (0: on the floor)
  double yaw_rad = 0.0;  ///< from M's x to T's x (0: upright, its top to the north)

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("id", id, config::Range{0, 100000});
    a.Optional("size_m", size_m, config::Range{0.005, 5.0});
    a.Required("x_m", x_m, config::Range{-1e4, 1e4});
    a.Required("y_m", y_m, config::Range{-1e4, 1e4});
    a.Optional("z_m", z_m, config::Range{-100.0, 100.0});
    a.Optional("yaw_rad", yaw_rad, config::Range{-10.0, 10.0});
  }
  bool operator==(const ReferenceTagConfig&) const = default;
};

/// One camera over the track.
struct CameraConfig {
  std::string name;
  /// Where its frames come from (docs/eye.md, "Sources"): `topic:NAME` (a simulated overhead
  /// camera, `/autodrive/cameras/NAME/image`), `device:N` or `device:/dev/videoN` (V4L2),
  /// `video:FILE`, `url:URL` (a stream OpenCV's FFmpeg backend opens), `images:DIR` (image
  /// files in name order).
  std::string source;
  /// Its intrinsics: an OpenCV calibration file (`autodrive-eye calibrate` writes one; the
  /// simulator's data sets carry one). Relative to the config file.
  std::string calibration;
  /// Its registered pose (`autodrive-eye register` writes one). Absent: the camera is
  /// registered from the reference tags in its first frames.
  std::optional<std::string> pose;
  /// For sources that carry no time: the frame rate, frames stamped index / rate (images:,
  /// video: files).
  double rate_hz = 30.0;
  /// The time from the middle of the exposure to the frame's arrival, subtracted from arrival
  /// stamps of live sources (device:, url:). Topic frames carry their exposure stamp.
  double latency_s = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Required("name", name);
    a.Required("source", source);
    a.Required("calibration", calibration);
    a.Optional("pose", pose);
    a.Optional("rate_hz", rate_hz, config::Range{0.1, 1000.0});
    a.Optional("latency_s", latency_s, config::Range{0.0, 10.0});
  }
  /// @throws InputError if the name is empty or not a plain word, or the source's scheme is
  /// not one of the above.
  void Validate() const;
  bool operator==(const CameraConfig&) const = default;
};

/// The filter per car and the search for tags.
struct TrackingConfig {
  /// Process noise: the car's acceleration (m/s²) and angular acceleration (rad/s²), white.
  /// A Nigel launches at up to its tyres' friction limit, μ g = 0.4 × 9.81 ≈ 3.9 m/s²: with 2.0,
  /// at 15 frames a second the frame after a launch was refused as an outlier (the small town's
  /// cars leaving their spawn).
  double accel_sigma = 4.0;
  double yaw_accel_sigma = 1.5;
  /// A measurement further than this (Mahalanobis distance squared, 3 degrees of freedom) from
  /// the prediction is an outlier; 16.3 is the 99.9% point.
  double gate_chi2 = 16.3;
  /// This many outliers in a row restart the car's filter from the measurement.
  int restart_after_outliers = 5;
  /// A car not seen for this long is lost (its track ends; a full scan looks for it).
  double lost_after_s = 0.5;
  /// A full-frame scan at least this often (new and lost tags, reference tags); between scans
  /// only the regions around the tracked cars' predicted tags are searched.
  double full_scan_period_s = 1.0;
  /// ... and at least this often while a configured car is not tracked (a camera that cannot
  /// see it keeps scanning at this rate).
  double missing_scan_period_s = 0.25;
  /// The margin around a predicted tag's corners searched, metres on the tag's plane.
  double roi_margin_m = 0.06;
  /// Corner noise assumed, px (a detection's covariance).
  double corner_sigma_px = 0.25;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("accel_sigma", accel_sigma, config::Range{1e-4, 100.0});
    a.Optional("yaw_accel_sigma", yaw_accel_sigma, config::Range{1e-4, 1000.0});
    a.Optional("gate_chi2", gate_chi2, config::Range{1.0, 1e6});
    a.Optional("restart_after_outliers", restart_after_outliers, config::Range{1, 1000});
    a.Optional("lost_after_s", lost_after_s, config::Range{0.01, 60.0});
    a.Optional("full_scan_period_s", full_scan_period_s, config::Range{0.0, 3600.0});
    a.Optional("missing_scan_period_s", missing_scan_period_s, config::Range{0.0, 3600.0});
    a.Optional("roi_margin_m", roi_margin_m, config::Range{0.0, 10.0});
    a.Optional("corner_sigma_px", corner_sigma_px, config::Range{0.01, 100.0});
  }
  bool operator==(const TrackingConfig&) const = default;
};

/// Checking each camera's registration as it runs.
struct RegistrationConfig {
  /// The reference tags' corners reprojected with the registered pose: a median error above
  /// this in `moved_after_checks` full scans in a row means the camera moved.
  double moved_threshold_px = 2.0;
  int moved_after_checks = 3;
  /// The reprojection RMS above which a registration is refused.
  double max_rms_px = 1.5;
  /// Frames whose reference-tag corners are averaged to register (a fixed camera).
  int frames = 5;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("moved_threshold_px", moved_threshold_px, config::Range{0.1, 1000.0});
    a.Optional("moved_after_checks", moved_after_checks, config::Range{1, 1000});
    a.Optional("max_rms_px", max_rms_px, config::Range{0.01, 1000.0});
    a.Optional("frames", frames, config::Range{1, 1000});
  }
  bool operator==(const RegistrationConfig&) const = default;
};

/// What `run` publishes besides the fleet poses.
struct OutputConfig {
  /// The devkit's `/autodrive/nigel_<n>/ips` per car (as the real car's IPS): only when the
  /// city's simulator does not publish it (the SCM refuses a city where both would).
  bool ips = false;
  /// An annotated image per camera on `/autodrive/eye/<camera>/debug_image`, at most this often
  /// (0: none).
  double debug_image_rate_hz = 0.0;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("ips", ips);
    a.Optional("debug_image_rate_hz", debug_image_rate_hz, config::Range{0.0, 100.0});
  }
  bool operator==(const OutputConfig&) const = default;
};

/// The whole configuration.
struct EyeConfig {
  DetectorConfig detector;
  std::vector<CameraConfig> cameras;
  std::vector<VehicleTagConfig> vehicles;
  std::vector<ReferenceTagConfig> reference_tags;
  TrackingConfig tracking;
  RegistrationConfig registration;
  OutputConfig outputs;

  template <typename Archive>
  void Serialize(Archive& a) {
    a.Optional("detector", detector);
    a.Required("cameras", cameras);
    a.Required("vehicles", vehicles);
    a.Optional("reference_tags", reference_tags);
    a.Optional("tracking", tracking);
    a.Optional("registration", registration);
    a.Optional("outputs", outputs);
  }
  /// Camera and vehicle names unique, tag ids unique across vehicles and reference tags, at
  /// least one camera. @throws InputError naming the duplicate.
  void Validate() const;
  bool operator==(const EyeConfig&) const = default;
};

/// Loads the Eye's configuration from `path`: a file whose top level is an `EyeConfig`, or a
/// city file (one with `name` and `map` keys) whose `eye` section is. Camera calibration and
/// pose files are made absolute, relative to the file's folder.
/// @throws ConfigError naming the file, line and key.
[[nodiscard]] EyeConfig LoadEyeConfig(const std::filesystem::path& path);

}  // namespace autodrive::eye
