#include "eye/localizer.h"

#include <fmt/format.h>

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
    case EyeEvent::Kind::kTagMounting:
      return "tag_mounting";
    case EyeEvent::Kind::kDuplicateTag:
      return "duplicate_tag";
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

// One configured car: its filter, its checks, and its last measurement (which another camera's
// frame of the same instant is compared with).
struct Localizer::Car {
  struct Measured {
    Time stamp{};
    std::size_t camera = 0;
    Eigen::Vector2d p_M = Eigen::Vector2d::Zero();
    bool applied = false;    // it changed the track
    bool withdrawn = false;  // taken back (another camera saw the id elsewhere)
  };
  VehicleTrack track;
  MountingCheck mounting;
  DuplicateCheck duplicates;
  std::optional<Measured> last;

  Car(const VehicleTagConfig& v, const TrackingConfig& t) : track(v, t), mounting(v.mount) {}
};

namespace {

std::string Metres(const Eigen::Vector2d& p) {
  return fmt::format("({:.2f}, {:.2f})", p.x(), p.y());
}

// The tag_mounting event's text: what was refused, the turn measured and what to check.
std::string MountingText(const VehicleTagConfig& v, const MountingFinding& f) {
  std::string text = fmt::format("{} of the last {} measurements refused", f.refused, f.of);
  if (!f.turn_rad) {
    return text + fmt::format(
                      " for {:.1f} s, and it has not moved far enough to compare its tag's "
                      "heading with its motion: check tag_yaw_deg, tag_ahead_m and tag_left_m",
                      f.refusing_for_s);
  }
  const double turn_deg = *f.turn_rad * 180.0 / kPi;
  if (std::abs(*f.turn_rad) < MountingCheck::kTurnToleranceRad) {
    return text + fmt::format(
                      ", but its tag's heading agrees with the car's motion ({:.1f}°): check "
                      "tag_ahead_m and tag_left_m (the tag's place on the roof), or whether the "
                      "car was carried",
                      turn_deg);
  }
  // To the nearest 5°: tags are glued square to the car, and a measured turn is good to a
  // degree or two.
  const long rounded = 5 * std::lround(std::abs(turn_deg) / 5.0);
  const std::string way = rounded == 180 ? "" : turn_deg > 0 ? " counter-clockwise" : " clockwise";
  const double fits = std::fmod(
      std::fmod(v.mount.yaw_deg + (turn_deg > 0 ? 1.0 : -1.0) * static_cast<double>(rounded),
                360.0) +
          360.0,
      360.0);
  if (f.only_backwards) {
    return fmt::format(
        "it has moved only against its measured heading ({} of the last {} measurements "
        "refused): its tag looks turned {}° from the configured mounting (the tag's heading "
        "differs from the car's motion by {:.1f}°), or the car has only reversed since it was "
        "first seen: check tag_yaw_deg (about {:.0f} would fit)",
        f.refused, f.of, rounded, turn_deg, fits);
  }
  return text + fmt::format(
                    "; its tag looks turned {}°{} from the configured mounting (the tag's heading "
                    "differs from the car's motion by {:.1f}°): check tag_yaw_deg (about {:.0f} "
                    "would fit)",
                    rounded, way, turn_deg, fits);
}

}  // namespace

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
  cars_.reserve(config_.vehicles.size());
  for (const VehicleTagConfig& v : config_.vehicles) {
    cars_.emplace_back(v, config_.tracking);
    // Two cameras' frames of one instant come one after the other: the first one's update is
    // taken back when the second shows the car's id elsewhere.
    cars_.back().track.set_undoable(cameras_.size() > 1);
  }
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
  for (const Car& car : cars_) {
    const VehicleTrack& track = car.track;
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
        cars_.begin(), cars_.end(), [&](const Car& c) { return c.track.active(stamp); }));
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
  const auto vehicle_of = [&](int id) -> std::optional<std::size_t> {
    for (std::size_t i = 0; i < config_.vehicles.size(); ++i) {
      if (config_.vehicles[i].tag_id == id) return i;
    }
    return std::nullopt;
  };
  // One tag found twice (by two regions) is kept once. A car's id at two places is two tags:
  // both stay, and neither measures the car (FindDuplicates); another id is kept once.
  std::sort(out.tags.begin(), out.tags.end(), [](const TagDetection& a, const TagDetection& b) {
    return a.id < b.id || (a.id == b.id && a.centre_px.x() < b.centre_px.x());
  });
  out.tags.erase(std::unique(out.tags.begin(), out.tags.end(),
                             [&](const TagDetection& a, const TagDetection& b) {
                               return a.id == b.id && (!vehicle_of(a.id) ||
                                                       (a.centre_px - b.centre_px).norm() < 2.0);
                             }),
                 out.tags.end());
  for (const TagDetection& d : out.tags) {
    const std::optional<std::size_t> vehicle = vehicle_of(d.id);
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
  FindDuplicates(out);
  return out;
}

void Localizer::FindDuplicates(FrameDetections& out) const {
  // The measurements are in id order, so one car's are next to each other.
  std::vector<VehicleMeasurement> kept;
  kept.reserve(out.vehicles.size());
  for (std::size_t i = 0; i < out.vehicles.size();) {
    std::size_t j = i + 1;
    while (j < out.vehicles.size() && out.vehicles[j].vehicle == out.vehicles[i].vehicle) ++j;
    if (j == i + 1) {
      kept.push_back(out.vehicles[i]);
    } else {
      DuplicateTags d{out.vehicles[i].vehicle, {}};
      const double size = config_.vehicles[d.vehicle].tag_size_m;
      bool apart = false;
      for (std::size_t k = i; k < j; ++k) {
        d.p_M.push_back(out.vehicles[k].tag.p_M);
        apart = apart || (out.vehicles[k].tag.p_M - out.vehicles[i].tag.p_M).norm() > size;
      }
      if (apart) {
        out.duplicates.push_back(std::move(d));
      } else {
        kept.push_back(out.vehicles[i]);  // one tag, found twice
      }
    }
    i = j;
  }
  out.vehicles = std::move(kept);
}

void Localizer::ExpireLocked(Time now, std::vector<EyeEvent>* events) {
  for (Car& car : cars_) {
    VehicleTrack& track = car.track;
    if (track.started() && !track.active(now) && now > track.last_update()) {
      track.Stop();
      if (events != nullptr) {
        events->push_back({EyeEvent::Kind::kVehicleLost, now, track.vehicle().name,
                           "not seen for " + std::to_string(config_.tracking.lost_after_s) + " s"});
      }
    }
  }
}

void Localizer::ExpireTracks(Time now, std::vector<EyeEvent>* events) {
  const std::lock_guard lock(mutex_);
  ExpireLocked(now, events);
}

std::vector<LocalizedVehicle> Localizer::Fuse(const FrameDetections& frame,
                                              std::vector<EyeEvent>* events,
                                              std::vector<std::size_t>* withdrawn) {
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
  ExpireLocked(frame.stamp, events);
  for (const DuplicateTags& d : frame.duplicates) {
    const VehicleTagConfig& v = config_.vehicles.at(d.vehicle);
    std::string where;
    for (const Eigen::Vector2d& p : d.p_M) where += (where.empty() ? "" : " and ") + Metres(p);
    counters_.duplicate_refusals += static_cast<long long>(d.p_M.size());
    Duplicated(cars_.at(d.vehicle), frame.stamp,
               fmt::format("{} tags with id {} in one frame of camera {}, at {} m", d.p_M.size(),
                           v.tag_id, cam.config.name, where),
               events);
  }
  for (const VehicleMeasurement& m : frame.vehicles) FuseVehicle(frame, m, events, withdrawn, out);
  for (std::size_t i = 0; i < cars_.size(); ++i) {
    if (cars_[i].duplicates.Clears(frame.stamp)) {
      const VehicleTagConfig& v = config_.vehicles[i];
      if (events != nullptr) {
        events->push_back({EyeEvent::Kind::kDuplicateTag, frame.stamp, v.name,
                           fmt::format("no second tag with id {} for {:.0f} s", v.tag_id,
                                       ToSeconds(DuplicateCheck::kClearAfter)),
                           true});
      }
    }
  }
  return out;
}

void Localizer::Duplicated(Car& car, Time stamp, const std::string& text,
                           std::vector<EyeEvent>* events) {
  if (car.duplicates.Seen(stamp) && events != nullptr) {
    events->push_back(
        {EyeEvent::Kind::kDuplicateTag, stamp, car.track.vehicle().name,
         text + ": all refused, and the car's track is neither started nor restarted while its "
                "id is in doubt; remove or cover the other tag"});
  }
}

void Localizer::FuseVehicle(const FrameDetections& frame, const VehicleMeasurement& m,
                            std::vector<EyeEvent>* events, std::vector<std::size_t>* withdrawn,
                            std::vector<LocalizedVehicle>& out) {
  Car& car = cars_.at(m.vehicle);
  const VehicleTagConfig& v = config_.vehicles.at(m.vehicle);
  const std::string& camera_name = cameras_.at(frame.camera)->config.name;
  // Another camera's frame of the same instant saw the id at a place this tag cannot be (its
  // size apart, and more than the car could drive in between): two tags, both refused.
  if (car.last && car.last->camera != frame.camera) {
    const Duration dt = frame.stamp > car.last->stamp ? frame.stamp - car.last->stamp
                                                      : car.last->stamp - frame.stamp;
    const double apart = (m.tag.p_M - car.last->p_M).norm();
    constexpr double kMaxSpeedMps = 1.0;
    if (dt <= kSameInstant && apart > v.tag_size_m + kMaxSpeedMps * ToSeconds(dt)) {
      if (car.last->applied && !car.last->withdrawn) {
        car.track.UndoLastUpdate();
        if (withdrawn != nullptr) withdrawn->push_back(m.vehicle);
      }
      counters_.duplicate_refusals += car.last->withdrawn ? 1 : 2;
      car.last->withdrawn = true;
      Duplicated(
          car, frame.stamp,
          fmt::format("tags with id {} at {} m in camera {} and at {} m in camera {} at "
                      "the same time",
                      v.tag_id, Metres(car.last->p_M), cameras_.at(car.last->camera)->config.name,
                      Metres(m.tag.p_M), camera_name),
          events);
      return;
    }
  }
  const TrackUpdate result = car.track.Update(frame.stamp, m.tag, !car.duplicates.active());
  car.last = Car::Measured{frame.stamp, frame.camera, m.tag.p_M,
                           result == TrackUpdate::kStarted || result == TrackUpdate::kUpdated ||
                               result == TrackUpdate::kRestarted,
                           false};
  ++counters_.measurements;
  if (result == TrackUpdate::kOutlier) ++counters_.outliers;
  if (result == TrackUpdate::kStarted && events != nullptr) {
    events->push_back(
        {EyeEvent::Kind::kVehicleFound, frame.stamp, v.name, "tracked from camera " + camera_name});
  }
  CheckMounting(car, frame.stamp, m.tag, result, events);
  if (result == TrackUpdate::kOutlier || result == TrackUpdate::kTooOld ||
      result == TrackUpdate::kHeld) {
    return;
  }
  const auto it = std::find_if(out.begin(), out.end(),
                               [&](const LocalizedVehicle& l) { return l.vehicle == m.vehicle; });
  if (it == out.end()) {
    out.push_back({m.vehicle, car.track.Predict(frame.stamp), {frame.camera}});
  } else {
    it->estimate = car.track.Predict(frame.stamp);
  }
}

void Localizer::CheckMounting(Car& car, Time stamp, const PlanarTagPose& tag, TrackUpdate result,
                              std::vector<EyeEvent>* events) {
  if (result == TrackUpdate::kTooOld || result == TrackUpdate::kHeld) return;
  const bool refused = result == TrackUpdate::kOutlier || result == TrackUpdate::kRestarted;
  const MountingCheck::Report report =
      car.mounting.Add(stamp, tag.p_M, car.track.VehicleYawOfTag(tag.yaw_rad), refused);
  if (report == MountingCheck::Report::kNothing || events == nullptr) return;
  const VehicleTagConfig& v = car.track.vehicle();
  if (report == MountingCheck::Report::kRaised) {
    events->push_back(
        {EyeEvent::Kind::kTagMounting, stamp, v.name, MountingText(v, car.mounting.finding())});
  } else {
    events->push_back({EyeEvent::Kind::kTagMounting, stamp, v.name,
                       "its measurements agree with its tag's mounting again", true});
  }
}

std::vector<LocalizedVehicle> Localizer::LocalizeFrame(std::size_t camera, Time stamp,
                                                       const cv::Mat& image,
                                                       std::vector<EyeEvent>* events,
                                                       std::vector<std::size_t>* withdrawn) {
  return Fuse(Detect(camera, stamp, image), events, withdrawn);
}

std::vector<LocalizedVehicle> Localizer::Estimates(Time stamp) const {
  const std::lock_guard lock(mutex_);
  std::vector<LocalizedVehicle> out;
  for (std::size_t i = 0; i < cars_.size(); ++i) {
    if (cars_[i].track.active(stamp)) out.push_back({i, cars_[i].track.Predict(stamp), {}});
  }
  return out;
}

LocalizerCounters Localizer::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace autodrive::eye
