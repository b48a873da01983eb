#pragma once
/// @file
/// The localiser: each camera's frames searched for tags (the regions around the tracked cars'
/// predicted tags, with periodic full-frame scans), each car's roof tag turned into a planar
/// pose, cameras registered to the map and watched for moves, and every car's filter fed by
/// all the cameras that see it.
///
/// Two steps per frame, so that cameras can detect on threads of their own while one thread
/// fuses: `Detect` (per camera, any thread; a camera's frames one at a time) and `Fuse` (in
/// time order, one thread). `LocalizeFrame` does both.

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/camera/camera_model.h"
#include "common/ids.h"
#include "common/time.h"
#include "eye/detector.h"
#include "eye/eye_config.h"
#include "eye/registration.h"
#include "eye/tag_pose.h"
#include "eye/track_checks.h"
#include "eye/tracker.h"

namespace autodrive::eye {

/// Something the operator should hear of.
struct EyeEvent {
  enum class Kind {
    kCameraRegistered,  ///< a camera's pose in the map was found
    kCameraMoved,       ///< a camera's reference tags no longer reproject where they should
    kCameraLost,        ///< a camera's frames stopped coming (the online service)
    kVehicleFound,      ///< a car's track started
    kVehicleLost,       ///< a car was not seen for `lost_after_s`
    /// A car's measurements disagree with its tag's configured mounting (`MountingCheck`):
    /// most of them refused, or its motion against its measured heading; the text gives the
    /// turn measured and the key to check.
    kTagMounting,
    /// Two tags with a car's id at once (one camera's frame, or two cameras' frames of one
    /// instant at places that cannot be one tag): both refused.
    kDuplicateTag,
  };
  Kind kind = Kind::kCameraRegistered;
  Time stamp{};
  std::string subject;  ///< the camera's or the car's name
  std::string text;     ///< what happened, for a person
  /// The end of an episode that an event of the same kind and subject raised
  /// (`tag_mounting`, `duplicate_tag`): an information, no longer a warning.
  bool cleared = false;
};
[[nodiscard]] const char* ToString(EyeEvent::Kind kind);

/// One car's roof tag measured in one frame.
struct VehicleMeasurement {
  std::size_t vehicle = 0;  ///< index into the configuration's vehicles
  PlanarTagPose tag;
  double decision_margin = 0.0;
};

/// Two or more tags with a car's id in one frame of one camera, at different places: none of
/// them is a measurement of the car.
struct DuplicateTags {
  std::size_t vehicle = 0;           ///< index into the configuration's vehicles
  std::vector<Eigen::Vector2d> p_M;  ///< each tag's centre at the roof's height, m
};

/// What `Detect` found in one frame of one camera.
struct FrameDetections {
  std::size_t camera = 0;
  Time stamp{};
  bool full_scan = false;
  std::vector<TagDetection> tags;  ///< every tag accepted, cars' and reference tags
  std::vector<VehicleMeasurement> vehicles;
  std::vector<DuplicateTags> duplicates;  ///< cars whose id was seen more than once
  DetectionStats stats;
  int unknown_tags = 0;   ///< ids neither a car's nor a reference tag's
  int refused_poses = 0;  ///< cars' tags whose corners do not fit a tag at the roof's height
};

/// A car's estimate as the localiser reports it.
struct LocalizedVehicle {
  std::size_t vehicle = 0;  ///< index into the configuration's vehicles
  VehicleEstimate estimate;
  std::vector<std::size_t> cameras;  ///< the cameras that measured it in this frame
};

/// Counters since the start.
struct LocalizerCounters {
  long long frames = 0;
  long long full_scans = 0;
  long long pixels_searched = 0;
  long long measurements = 0;
  long long outliers = 0;
  long long unknown_tags = 0;
  long long refused_poses = 0;
  long long duplicate_refusals = 0;  ///< measurements refused because their id was seen twice
};

/// The localiser of one configuration. Thread-safety: `Detect` may run for different cameras
/// on different threads at once, and beside `Fuse`; `Fuse`, `Register`, `Estimates` and the
/// accessors take a lock. Not copyable or movable.
class Localizer {
 public:
  /// Loads every camera's calibration and, where configured, its pose.
  /// @throws ConfigError / InputError when a file is missing or bad.
  explicit Localizer(EyeConfig config);
  ~Localizer();
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  [[nodiscard]] const EyeConfig& config() const { return config_; }
  [[nodiscard]] std::size_t camera_count() const { return cameras_.size(); }
  /// The camera's name and model (its pose as registered, identity before).
  [[nodiscard]] camera::Camera Camera(std::size_t camera) const;
  [[nodiscard]] bool registered(std::size_t camera) const;

  /// Registers `camera` from the detections of frames of it that did not move (see
  /// `RegisterCamera`) and keeps the result. `std::nullopt` with the reason in `why` when it
  /// failed (the camera keeps its previous registration, if any).
  std::optional<Registration> Register(std::size_t camera,
                                       const std::vector<std::vector<TagDetection>>& frames,
                                       std::string* why);

  /// Forgets `camera`'s registration: it registers again from its next frames that show
  /// reference tags (after it moved, when the operator says so).
  void Reregister(std::size_t camera);

  /// Searches a frame of `camera` (CV_8UC1 grey, or BGR converted here) taken at `stamp`: the
  /// whole frame when a full scan is due (its first frame, `full_scan_period_s` since the last,
  /// or not yet registered; `force_full` too), else the regions around the tracked cars'
  /// predicted tags. Cars' tags are turned into planar poses when the camera is registered.
  [[nodiscard]] FrameDetections Detect(std::size_t camera, Time stamp, const cv::Mat& image,
                                       bool force_full = false);

  /// Feeds a frame's detections to the cars' filters (call in time order; a frame up to 0.2 s
  /// late is still fused), registers a camera not yet registered once it has seen
  /// `registration.frames` frames with reference tags, checks a registered camera's reference
  /// tags on full scans, and ends the tracks of cars not seen for `lost_after_s`. Returns the
  /// cars measured in this frame (their estimates at its stamp); events are appended to
  /// `events`.
  ///
  /// A car whose id this frame shows twice is not measured in it, nor is one that another
  /// camera's frame of the same instant (within `kSameInstant`) saw at a place that cannot be
  /// the same tag: that frame's measurement is taken back from the filter too, and the car is
  /// appended to `withdrawn` (when given) so that a caller collecting one instant's frames
  /// drops what it took from that frame. While a car's id is in doubt (`DuplicateCheck`) its
  /// track is neither started nor restarted. Each car's measurements go through its
  /// `MountingCheck`; both checks raise their events once per episode.
  std::vector<LocalizedVehicle> Fuse(const FrameDetections& frame, std::vector<EyeEvent>* events,
                                     std::vector<std::size_t>* withdrawn = nullptr);

  /// Ends the tracks of cars not seen for `lost_after_s` at `now` (`vehicle_lost`, stamped
  /// `now`), as `Fuse` does at each frame: for when no frame comes (a camera lost). Thread-safe
  /// against `Fuse`.
  void ExpireTracks(Time now, std::vector<EyeEvent>* events);

  /// Two cameras' frames this close in time show one instant (unsynchronised 30 Hz cameras'
  /// frames are at most 17 ms apart).
  static constexpr Duration kSameInstant = std::chrono::milliseconds(25);

  /// Detect, then Fuse.
  std::vector<LocalizedVehicle> LocalizeFrame(std::size_t camera, Time stamp, const cv::Mat& image,
                                              std::vector<EyeEvent>* events,
                                              std::vector<std::size_t>* withdrawn = nullptr);

  /// Every car with an active track, predicted to `stamp`.
  [[nodiscard]] std::vector<LocalizedVehicle> Estimates(Time stamp) const;

  [[nodiscard]] LocalizerCounters counters() const;

 private:
  struct CameraState;
  struct Car;
  [[nodiscard]] std::vector<cv::Rect> PredictedRegions(const CameraState& cam, Time stamp) const;
  void FindDuplicates(FrameDetections& out) const;
  // `ExpireTracks` with `mutex_` held.
  void ExpireLocked(Time now, std::vector<EyeEvent>* events);
  // Fuse's parts (the caller holds mutex_).
  void FuseVehicle(const FrameDetections& frame, const VehicleMeasurement& m,
                   std::vector<EyeEvent>* events, std::vector<std::size_t>* withdrawn,
                   std::vector<LocalizedVehicle>& out);
  void Duplicated(Car& car, Time stamp, const std::string& text, std::vector<EyeEvent>* events);
  void CheckMounting(Car& car, Time stamp, const PlanarTagPose& tag, TrackUpdate result,
                     std::vector<EyeEvent>* events);

  EyeConfig config_;
  std::vector<std::unique_ptr<CameraState>> cameras_;
  mutable std::mutex mutex_;  // guards cars_, counters_ and the cameras' registration
  std::vector<Car> cars_;     // per configured vehicle
  LocalizerCounters counters_;
};

/// Converts a frame to 8-bit grey (CV_8UC1 as it is, CV_8UC3 from BGR).
/// @throws InputError for another type.
[[nodiscard]] cv::Mat ToGrey(const cv::Mat& image);

}  // namespace autodrive::eye
