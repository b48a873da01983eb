#include "eye/registration.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "common/error.h"

namespace autodrive::eye {

namespace {

const ReferenceTagConfig* FindReference(const std::vector<ReferenceTagConfig>& references, int id) {
  for (const ReferenceTagConfig& r : references) {
    if (r.id == id) return &r;
  }
  return nullptr;
}

std::array<Eigen::Vector3d, 4> MapCorners(const ReferenceTagConfig& r) {
  const Eigen::Isometry3d X_MT = Eigen::Translation3d(r.x_m, r.y_m, r.z_m) *
                                 Eigen::AngleAxisd(r.yaw_rad, Eigen::Vector3d::UnitZ());
  std::array<Eigen::Vector3d, 4> corners = TagCorners(r.size_m);
  for (Eigen::Vector3d& c : corners) c = X_MT * c;
  return corners;
}

cv::Mat CameraMatrix(const camera::Intrinsics& in) {
  cv::Mat K;
  cv::eigen2cv(in.CameraMatrix(), K);
  return K;
}

cv::Mat Distortion(const camera::Intrinsics& in) {
  cv::Mat d(1, static_cast<int>(in.distortion.size()), CV_64F);
  for (std::size_t k = 0; k < in.distortion.size(); ++k) {
    d.at<double>(0, static_cast<int>(k)) = in.distortion[k];
  }
  return in.distortion.empty() ? cv::Mat() : d;
}

}  // namespace

std::optional<Registration> RegisterCamera(const camera::CameraModel& model,
                                           const std::vector<std::vector<TagDetection>>& frames,
                                           const std::vector<ReferenceTagConfig>& references,
                                           double max_rms_px, std::string* why) {
  const auto fail = [&](const std::string& reason) -> std::optional<Registration> {
    if (why != nullptr) *why = reason;
    return std::nullopt;
  };
  // Each reference tag's corners, averaged over the frames that saw it.
  struct Sum {
    std::array<Eigen::Vector2d, 4> corners{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                           Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
    int n = 0;
  };
  std::map<int, Sum> sums;
  for (const auto& frame : frames) {
    for (const TagDetection& d : frame) {
      if (FindReference(references, d.id) == nullptr) continue;
      Sum& s = sums[d.id];
      for (std::size_t k = 0; k < 4; ++k) s.corners[k] += d.corners_px[k];
      ++s.n;
    }
  }
  if (sums.size() < 2) {
    return fail("saw " + std::to_string(sums.size()) +
                " reference tag(s); registration needs at least 2 of the " +
                std::to_string(references.size()) + " configured");
  }
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  Registration result;
  result.frames = static_cast<int>(frames.size());
  for (const auto& [id, s] : sums) {
    const std::array<Eigen::Vector3d, 4> corners = MapCorners(*FindReference(references, id));
    for (std::size_t k = 0; k < 4; ++k) {
      object.emplace_back(corners[k].x(), corners[k].y(), corners[k].z());
      const Eigen::Vector2d px = s.corners[k] / s.n;
      image.emplace_back(px.x(), px.y());
    }
    result.tag_ids.push_back(id);
  }
  const cv::Mat K = CameraMatrix(model.intrinsics());
  const cv::Mat dist = Distortion(model.intrinsics());
  cv::Mat rvec, tvec;
  std::vector<cv::Point2d> projected;
  try {
    if (!cv::solvePnP(object, image, K, dist, rvec, tvec, false, cv::SOLVEPNP_SQPNP)) {
      return fail("PnP found no pose");
    }
    cv::solvePnPRefineLM(
        object, image, K, dist, rvec, tvec,
        cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-12));
    cv::projectPoints(object, rvec, tvec, K, dist, projected);
  } catch (const cv::Exception& e) {
    // Degenerate corners (reference tags configured on top of each other, say).
    return fail(std::string("OpenCV could not solve for the pose: ") + e.what());
  }
  double sum2 = 0;
  for (std::size_t i = 0; i < image.size(); ++i) {
    const double e = cv::norm(projected[i] - image[i]);
    sum2 += e * e;
    result.max_px = std::max(result.max_px, e);
  }
  result.rms_px = std::sqrt(sum2 / static_cast<double>(image.size()));
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d R_CM;
  Eigen::Vector3d p_CM;
  cv::cv2eigen(R, R_CM);
  cv::cv2eigen(tvec, p_CM);
  Eigen::Isometry3d X_CM = Eigen::Isometry3d::Identity();
  X_CM.linear() = R_CM;
  X_CM.translation() = p_CM;
  result.X_MC = X_CM.inverse();
  if (result.rms_px > max_rms_px) {
    return fail("the reference tags reproject with " + std::to_string(result.rms_px) +
                " px RMS, more than the " + std::to_string(max_rms_px) +
                " px allowed (a tag's configured pose, the calibration, or a tag seen wrongly)");
  }
  return result;
}

std::optional<double> ReferenceReprojectionError(
    const camera::Camera& camera, const std::vector<TagDetection>& detections,
    const std::vector<ReferenceTagConfig>& references) {
  std::vector<double> errors;
  for (const TagDetection& d : detections) {
    const ReferenceTagConfig* r = FindReference(references, d.id);
    if (r == nullptr) continue;
    const std::array<Eigen::Vector3d, 4> corners = MapCorners(*r);
    for (std::size_t k = 0; k < 4; ++k) {
      const auto px = camera.ProjectFromParent(corners[k]);
      errors.push_back(px ? (*px - d.corners_px[k]).norm() : 1e9);
    }
  }
  if (errors.empty()) return std::nullopt;
  const auto mid = errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2);
  std::nth_element(errors.begin(), mid, errors.end());
  return *mid;
}

bool MoveDetector::Check(double median_error_px) {
  if (median_error_px > config_.moved_threshold_px) {
    ++bad_in_a_row_;
  } else {
    bad_in_a_row_ = 0;
  }
  if (!moved_ && bad_in_a_row_ >= config_.moved_after_checks) {
    moved_ = true;
    return true;
  }
  return false;
}

void MoveDetector::Reset() {
  bad_in_a_row_ = 0;
  moved_ = false;
}

void SavePose(const std::filesystem::path& path, const std::string& name,
              const std::string& frame_id, const Registration& registration) {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "camera" << YAML::Value << name;
  out << YAML::Key << "frame_id" << YAML::Value << frame_id;
  out << YAML::Key << "parent_frame" << YAML::Value << "map";
  out << YAML::Key << "X_parent_optical" << YAML::Value << YAML::BeginSeq;
  for (int r = 0; r < 4; ++r) {
    out << YAML::Flow << YAML::BeginSeq;
    for (int c = 0; c < 4; ++c) out << registration.X_MC.matrix()(r, c);
    out << YAML::EndSeq;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "rms_px" << YAML::Value << registration.rms_px;
  out << YAML::Key << "max_px" << YAML::Value << registration.max_px;
  out << YAML::Key << "frames" << YAML::Value << registration.frames;
  out << YAML::Key << "tag_ids" << YAML::Value << YAML::Flow << registration.tag_ids;
  out << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << '\n';
  file.close();
  AUTODRIVE_THROW_UNLESS(file.good(), "cannot write " << path.string());
}

Eigen::Isometry3d LoadPose(const std::filesystem::path& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::BadFile&) {
    throw ConfigError(path.string() + ": cannot read the camera pose file");
  } catch (const YAML::Exception& e) {
    throw ConfigError(path.string() + ":" + std::to_string(e.mark.line + 1) +
                      ": YAML syntax error (" + e.msg + ")");
  }
  const auto bad = [&](const std::string& what) {
    return ConfigError(path.string() + ": " + what);
  };
  if (!root.IsMap()) throw bad("not a mapping (expected camera, parent_frame, X_parent_optical)");
  const YAML::Node parent = root["parent_frame"];
  if (!parent || !parent.IsScalar() || parent.as<std::string>() != "map") {
    throw bad("parent_frame: must be map (a camera registered to the map), got " +
              (parent && parent.IsScalar() ? parent.as<std::string>() : std::string("nothing")));
  }
  const YAML::Node X = root["X_parent_optical"];
  if (!X || !X.IsSequence() || X.size() != 4) {
    throw bad("X_parent_optical: expected 4 rows of 4 numbers");
  }
  Eigen::Matrix4d m;
  for (std::size_t r = 0; r < 4; ++r) {
    if (!X[r].IsSequence() || X[r].size() != 4) {
      throw bad("X_parent_optical: row " + std::to_string(r + 1) + " is not 4 numbers");
    }
    for (std::size_t c = 0; c < 4; ++c) {
      try {
        m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = X[r][c].as<double>();
      } catch (const YAML::Exception&) {
        throw bad("X_parent_optical: row " + std::to_string(r + 1) + " holds a non-number");
      }
    }
  }
  if (!m.allFinite()) throw bad("X_parent_optical: holds a value that is not finite");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      std::abs(R.determinant() - 1) > 1e-6 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-12) {
    throw bad(
        "X_parent_optical: not a rigid transform (rotation not orthonormal or last row not "
        "0 0 0 1)");
  }
  Eigen::Isometry3d X_MC = Eigen::Isometry3d::Identity();
  X_MC.linear() = R;
  X_MC.translation() = m.topRightCorner<3, 1>();
  return X_MC;
}

}  // namespace autodrive::eye
