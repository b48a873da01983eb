#include "eye/localizer.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "common/error.h"

namespace autodrive::eye {

const char* ToString(EyeEvent::Kind kind) {
  switch (kind) {
    case EyeEvent::Kind::kCameraRegistered:
      return "camera_registered";
    case EyeEvent::Kind::kCameraMoved:
      return "camera_moved";
    case EyeEvent::Kind::kCameraLost:
      return "camera_lost";
    case EyeEvent::Kind::kVehicleFound:
      return "vehicle_found";
    case EyeEvent::Kind::kVehicleLost:
      return "vehicle_lost";
  }
  return "?";
}

cv::Mat ToGrey(const cv::Mat& image) {
  if (image.type() == CV_8UC1) return image;
  AUTODRIVE_THROW_UNLESS(image.type() == CV_8UC3,
                         "a frame must be 8-bit grey or BGR, got OpenCV type " << image.type());
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

struct Localizer::CameraState {
  CameraConfig config;
  camera::Camera camera;
  bool registered = false;                // guarded by the localiser's mutex
  bool scanned_since_registered = false;  // guarded by the localiser's mutex
  MoveDetector move;
  // Used by Detect only (one frame of a camera at a time).
  TagDetector detector;
  std::optional<Time> last_full_scan;
  // Used by Fuse only.
  std::vector<std::vector<TagDetection>> registration_frames;

  CameraState(const CameraConfig& c, camera::Camera cam, const EyeConfig& eye)
      : config(c), camera(std::move(cam)), move(eye.registration), detector(eye.detector) {}
};

Localizer::Localizer(EyeConfig config) : config_(std::move(config)) {
  config_.Validate();
  for (const CameraConfig& c : config_.cameras) {
    camera::Camera cam{c.name, c.name, "map",
                       camera::CameraModel(camera::LoadOpenCvCalibration(c.calibration)),
                       Eigen::Isometry3d::Identity()};
    auto state = std::make_unique<CameraState>(c, std::move(cam), config_);
    if (c.pose) {
      state->camera.X_PC = LoadPose(*c.pose);
      state->registered = true;
    }
    cameras_.push_back(std::move(state));
  }
  for (const VehicleTagConfig& v : config_.vehicles) tracks_.emplace_back(v, config_.tracking);
}

Localizer::~Localizer() = default;

camera::Camera Localizer::Camera(std::size_t camera) const {
  const std::lock_guard lock(mutex_);
  return cameras_.at(camera)->camera;
}

bool Localizer::registered(std::size_t camera) const {
  const std::lock_guard lock(mutex_);
  return cameras_.at(camera)->registered;
}

std::optional<Registration> Localizer::Register(
    std::size_t camera, const std::vector<std::vector<TagDetection>>& frames, std::string* why) {
  CameraState& cam = *cameras_.at(camera);
  const auto result = RegisterCamera(cam.camera.model, frames, config_.reference_tags,
                                     config_.registration.max_rms_px, why);
  if (result) {
    const std::lock_guard lock(mutex_);
    cam.camera.X_PC = result->X_MC;
    cam.registered = true;
    cam.scanned_since_registered = false;
    cam.move.Reset();
  }
  return result;
}

void Localizer::Reregister(std::size_t camera) {
  const std::lock_guard lock(mutex_);
  CameraState& cam = *cameras_.at(camera);
  cam.registered = false;
  cam.move.Reset();
}

std::vector<cv::Rect> Localizer::PredictedRegions(const CameraState& cam, Time stamp) const {
  // Guarded by mutex_ (the caller holds it).
  std::vector<cv::Rect> rects;
  const cv::Rect image(0, 0, cam.camera.model.intrinsics().width_px,
                       cam.camera.model.intrinsics().height_px);
  for (const VehicleTrack& track : tracks_) {
    if (!track.active(stamp)) continue;
    const VehicleEstimate e = track.Predict(stamp);
    const VehicleTagConfig& v = track.vehicle();
    // The tag's square grown by the margin and three standard deviations of the predicted
    // position, at the roof's height, projected: its bounding rectangle.
    const double sigma = std::sqrt(std::max(e.covariance(0, 0), e.covariance(1, 1)));
    const double half = v.tag_size_m * 0.5 * std::sqrt(2.0) + config_.tracking.roi_margin_m +
                        3.0 * std::min(sigma, 0.5);
    double u0 = 1e30, v0 = 1e30, u1 = -1e30, v1 = -1e30;
    bool ok = true;
    for (int k = 0; k < 4 && ok; ++k) {
      const Eigen::Vector3d p(e.tag_centre_M.x() + ((k & 1) ? half : -half),
                              e.tag_centre_M.y() + ((k & 2) ? half : -half), v.tag_height_m);
      const auto px = cam.camera.ProjectFromParent(p);
      if (!px) {
        ok = false;
        break;
      }
      u0 = std::min(u0, px->x());
      v0 = std::min(v0, px->y());
      u1 = std::max(u1, px->x());
      v1 = std::max(v1, px->y());
    }
    if (!ok) continue;
    const cv::Rect r(static_cast<int>(std::floor(u0)) - 2, static_cast<int>(std::floor(v0)) - 2,
                     static_cast<int>(std::ceil(u1 - u0)) + 5,
                     static_cast<int>(std::ceil(v1 - v0)) + 5);
    const cv::Rect clipped = r & image;
    if (clipped.area() > 0) rects.push_back(clipped);
  }
  return MergeRects(std::move(rects));
}

FrameDetections Localizer::Detect(std::size_t camera, Time stamp, const cv::Mat& image,
                                  bool force_full) {
  CameraState& cam = *cameras_.at(camera);
  const cv::Mat grey = ToGrey(image);
  const camera::Intrinsics& in = cam.camera.model.intrinsics();
  AUTODRIVE_THROW_UNLESS(grey.cols == in.width_px && grey.rows == in.height_px,
                         "camera " << cam.config.name << ": a frame of " << grey.cols << "x"
                                   << grey.rows << " px, but its calibration is for " << in.width_px
                                   << "x" << in.height_px);
  FrameDetections out;
  out.camera = camera;
  out.stamp = stamp;
  std::optional<camera::Camera> placed;
  bool registered = false, first_since_registered = false;
  std::size_t tracked = 0;
  std::vector<cv::Rect> regions;
  {
    const std::lock_guard lock(mutex_);
    registered = cam.registered;
    first_since_registered = registered && !cam.scanned_since_registered;
    cam.scanned_since_registered = registered;
    placed = cam.camera;
    if (registered) regions = PredictedRegions(cam, stamp);
    tracked = static_cast<std::size_t>(std::count_if(
        tracks_.begin(), tracks_.end(), [&](const VehicleTrack& t) { return t.active(stamp); }));
  }
  // A full scan: periodically, more often while a configured car is not tracked, and on the
  // first frame after the camera was registered.
  const double since = cam.last_full_scan ? ToSeconds(stamp - *cam.last_full_scan) : 1e300;
  const double period =
      tracked < config_.vehicles.size()
          ? std::min(config_.tracking.full_scan_period_s, config_.tracking.missing_scan_period_s)
          : config_.tracking.full_scan_period_s;
  out.full_scan =
      force_full || !registered || first_since_registered || since >= period || since < 0;
  if (out.full_scan) {
    cam.last_full_scan = stamp;
    out.tags = cam.detector.Detect(grey, &out.stats);
  } else {
    out.tags = cam.detector.Detect(grey, regions, &out.stats);
  }
  // A tag seen in two merged-apart regions would come twice: keep the first of each id.
  std::sort(out.tags.begin(), out.tags.end(),
            [](const TagDetection& a, const TagDetection& b) { return a.id < b.id; });
  out.tags.erase(
      std::unique(out.tags.begin(), out.tags.end(),
                  [](const TagDetection& a, const TagDetection& b) { return a.id == b.id; }),
      out.tags.end());
  for (const TagDetection& d : out.tags) {
    std::optional<std::size_t> vehicle;
    for (std::size_t i = 0; i < config_.vehicles.size(); ++i) {
      if (config_.vehicles[i].tag_id == d.id) vehicle = i;
    }
    if (!vehicle) {
      const bool reference =
          std::any_of(config_.reference_tags.begin(), config_.reference_tags.end(),
                      [&](const ReferenceTagConfig& r) { return r.id == d.id; });
      if (!reference) ++out.unknown_tags;
      continue;
    }
    if (!registered) continue;
    const VehicleTagConfig& v = config_.vehicles[*vehicle];
    const auto pose = LocateHorizontalTag(*placed, d, v.tag_size_m, v.tag_height_m,
                                          config_.tracking.corner_sigma_px);
    // The geometric check: a real roof tag's corners fit a square of its size at the roof's
    // height to a fraction of a pixel; a false quad, or a tag printed at another size or lying
    // elsewhere, does not.
    const double max_rms = std::max(1.0, 4.0 * config_.tracking.corner_sigma_px);
    if (!pose || pose->rms_px > max_rms) {
      ++out.refused_poses;
      continue;
    }
    out.vehicles.push_back({*vehicle, *pose, d.decision_margin});
  }
  return out;
}

std::vector<LocalizedVehicle> Localizer::Fuse(const FrameDetections& frame,
                                              std::vector<EyeEvent>* events) {
  CameraState& cam = *cameras_.at(frame.camera);
  const auto emit = [&](EyeEvent::Kind kind, const std::string& subject, const std::string& text) {
    if (events != nullptr) events->push_back({kind, frame.stamp, subject, text});
  };
  bool registered = false;
  {
    const std::lock_guard lock(mutex_);
    registered = cam.registered;
    ++counters_.frames;
    if (frame.full_scan) ++counters_.full_scans;
    counters_.pixels_searched += frame.stats.pixels;
    counters_.unknown_tags += frame.unknown_tags;
    counters_.refused_poses += frame.refused_poses;
  }
  // Registration: from the first frames that show reference tags.
  if (!registered && frame.full_scan) {
    const auto references =
        std::count_if(frame.tags.begin(), frame.tags.end(), [&](const TagDetection& d) {
          return std::any_of(config_.reference_tags.begin(), config_.reference_tags.end(),
                             [&](const ReferenceTagConfig& r) { return r.id == d.id; });
        });
    if (references >= 2) cam.registration_frames.push_back(frame.tags);
    if (static_cast<int>(cam.registration_frames.size()) >= config_.registration.frames) {
      std::string why;
      const auto r = Register(frame.camera, cam.registration_frames, &why);
      cam.registration_frames.clear();
      if (r) {
        emit(EyeEvent::Kind::kCameraRegistered, cam.config.name,
             "registered to the map from " + std::to_string(r->tag_ids.size()) +
                 " reference tags, " + std::to_string(r->rms_px) + " px RMS");
      }
    }
  }
  // The reference tags still where the registration put them?
  if (registered && frame.full_scan) {
    const camera::Camera placed = Camera(frame.camera);
    const auto error = ReferenceReprojectionError(placed, frame.tags, config_.reference_tags);
    if (error) {
      const std::lock_guard lock(mutex_);
      if (cam.move.Check(*error)) {
        emit(EyeEvent::Kind::kCameraMoved, cam.config.name,
             "the reference tags reproject " + std::to_string(*error) +
                 " px (median) from where the registration puts them: the camera moved; "
                 "register it again");
      }
    }
  }
  std::vector<LocalizedVehicle> out;
  const std::lock_guard lock(mutex_);
  // Cars not seen for lost_after_s are lost (before this frame's measurements restart them).
  for (VehicleTrack& track : tracks_) {
    if (track.started() && !track.active(frame.stamp) && frame.stamp > track.last_update()) {
      track.Stop();
      emit(EyeEvent::Kind::kVehicleLost, track.vehicle().name,
           "not seen for " + std::to_string(config_.tracking.lost_after_s) + " s");
    }
  }
  for (const VehicleMeasurement& m : frame.vehicles) {
    VehicleTrack& track = tracks_.at(m.vehicle);
    const TrackUpdate result = track.Update(frame.stamp, m.tag);
    ++counters_.measurements;
    if (result == TrackUpdate::kOutlier) ++counters_.outliers;
    if (result == TrackUpdate::kStarted) {
      emit(EyeEvent::Kind::kVehicleFound, track.vehicle().name,
           "tracked from camera " + cam.config.name);
    }
    if (result == TrackUpdate::kOutlier || result == TrackUpdate::kTooOld) continue;
    const auto it = std::find_if(out.begin(), out.end(),
                                 [&](const LocalizedVehicle& l) { return l.vehicle == m.vehicle; });
    if (it == out.end()) {
      out.push_back({m.vehicle, track.Predict(frame.stamp), {frame.camera}});
    } else {
      it->estimate = track.Predict(frame.stamp);
    }
  }
  return out;
}

std::vector<LocalizedVehicle> Localizer::LocalizeFrame(std::size_t camera, Time stamp,
                                                       const cv::Mat& image,
                                                       std::vector<EyeEvent>* events) {
  return Fuse(Detect(camera, stamp, image), events);
}

std::vector<LocalizedVehicle> Localizer::Estimates(Time stamp) const {
  const std::lock_guard lock(mutex_);
  std::vector<LocalizedVehicle> out;
  for (std::size_t i = 0; i < tracks_.size(); ++i) {
    if (tracks_[i].active(stamp)) out.push_back({i, tracks_[i].Predict(stamp), {}});
  }
  return out;
}

LocalizerCounters Localizer::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace autodrive::eye
