#include "common/camera/camera_model.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <sstream>
#include <string>
#include <utility>

#include <opencv2/core.hpp>
#include <opencv2/core/persistence.hpp>

#include "common/eigen_text.h"
#include "common/error.h"

namespace autodrive::camera {
namespace {

// Undistortion (see the header): iteration cap, the residual at which Newton stops early and
// the residual at which the result is accepted, both relative to 1 + |distorted point|.
constexpr int kMaxUndistortIterations = 20;
constexpr int kMaxStepHalvings = 40;
constexpr double kUndistortStopResidual = 1e-15;
constexpr double kUndistortAcceptResidual = 1e-12;

// The valid region (see CameraModel): ray angles are sampled at this step, then the first fold
// is bisected to this many halvings (far below double precision of the angle).
constexpr double kFoldScanStepRad = 0.01 * kPi / 180.0;
constexpr int kFoldBisections = 100;

// The radial factor R(s) = N(s) / D(s), s = r^2, with N = 1 + k1 s + k2 s^2 + k3 s^3 and
// D = 1 + k4 s + k5 s^2 + k6 s^3, and its derivative dR/ds.
struct RadialFactor {
  double value = 1.0;
  double derivative = 0.0;
  double denominator = 1.0;
};

RadialFactor Radial(const std::array<double, 8>& k, double s) {
  const double k1 = k[0], k2 = k[1], k3 = k[4], k4 = k[5], k5 = k[6], k6 = k[7];
  const double n = 1.0 + s * (k1 + s * (k2 + s * k3));
  const double dn = k1 + s * (2.0 * k2 + 3.0 * k3 * s);
  const double d = 1.0 + s * (k4 + s * (k5 + s * k6));
  const double dd = k4 + s * (2.0 * k5 + 3.0 * k6 * s);
  return {.value = n / d, .derivative = (dn * d - n * dd) / (d * d), .denominator = d};
}

// True if the radial distortion f(r) = r R(r^2) is strictly increasing at r = sqrt(s) and its
// denominator is positive: f'(r) = R + 2 s dR/ds > 0.
bool RadialIsIncreasing(const std::array<double, 8>& k, double s) {
  const RadialFactor radial = Radial(k, s);
  return radial.denominator > 0.0 && radial.value + 2.0 * s * radial.derivative > 0.0;
}

// The normalised radius up to which the radial distortion is one-to-one, at most
// tan(kMaxRayAngleRad): the ray angle is scanned from the axis outwards and the first angle
// where f' <= 0 or D <= 0 is bisected.
double MaxNormalizedRadius(const std::array<double, 8>& k) {
  const auto good = [&k](double angle_rad) {
    const double r = std::tan(angle_rad);
    return RadialIsIncreasing(k, r * r);
  };
  double last_good = 0.0;
  for (int i = 1;; ++i) {
    const double angle = std::min(i * kFoldScanStepRad, kMaxRayAngleRad);
    if (!good(angle)) {
      double lo = last_good;
      double hi = angle;
      for (int j = 0; j < kFoldBisections && lo < hi; ++j) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) {
          break;
        }
        (good(mid) ? lo : hi) = mid;
      }
      return std::tan(lo);
    }
    last_good = angle;
    if (angle >= kMaxRayAngleRad) {
      return std::tan(kMaxRayAngleRad);
    }
  }
}

// The distorted normalised point and the Jacobian of the distortion map at (x, y).
struct Distorted {
  Eigen::Vector2d xy;
  Eigen::Matrix2d jacobian;
};

Distorted DistortWithJacobian(const std::array<double, 8>& k, const Eigen::Vector2d& xy) {
  const double x = xy.x();
  const double y = xy.y();
  const double p1 = k[2];
  const double p2 = k[3];
  const double s = x * x + y * y;
  const RadialFactor radial = Radial(k, s);
  const double r = radial.value;
  const double dr = radial.derivative;
  Distorted out;
  out.xy = Eigen::Vector2d(x * r + 2.0 * p1 * x * y + p2 * (s + 2.0 * x * x),
                           y * r + p1 * (s + 2.0 * y * y) + 2.0 * p2 * x * y);
  const double cross = 2.0 * x * y * dr + 2.0 * p1 * x + 2.0 * p2 * y;
  out.jacobian << r + 2.0 * x * x * dr + 2.0 * p1 * y + 6.0 * p2 * x, cross,  //
      cross, r + 2.0 * y * y * dr + 6.0 * p1 * y + 2.0 * p2 * x;
  return out;
}

bool IsSupportedDistortionSize(std::size_t n) { return n == 0 || n == 4 || n == 5 || n == 8; }

// What to say about an unsupported number of distortion coefficients.
std::string DistortionSizeProblem(std::size_t n) {
  std::ostringstream os;
  if (n == 12 || n == 14) {
    os << "OpenCV's " << n << "-coefficient model ("
       << (n == 12 ? "thin prism" : "thin prism and tilted sensor") << ") is not supported (got "
       << n << " coefficients; expected 4, 5 or 8)";
  } else {
    os << "expected 4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]]), got " << n;
  }
  return os.str();
}

}  // namespace

// --- Intrinsics ---

void Intrinsics::Validate() const {
  AUTODRIVE_THROW_UNLESS(width_px > 0, "Intrinsics: width_px must be positive, got " << width_px);
  AUTODRIVE_THROW_UNLESS(height_px > 0,
                         "Intrinsics: height_px must be positive, got " << height_px);
  AUTODRIVE_THROW_UNLESS(std::isfinite(fx_px) && fx_px > 0.0,
                         "Intrinsics: fx_px must be finite and positive, got " << fx_px);
  AUTODRIVE_THROW_UNLESS(std::isfinite(fy_px) && fy_px > 0.0,
                         "Intrinsics: fy_px must be finite and positive, got " << fy_px);
  AUTODRIVE_THROW_UNLESS(std::isfinite(cx_px), "Intrinsics: cx_px must be finite, got " << cx_px);
  AUTODRIVE_THROW_UNLESS(std::isfinite(cy_px), "Intrinsics: cy_px must be finite, got " << cy_px);
  AUTODRIVE_THROW_UNLESS(IsSupportedDistortionSize(distortion.size()),
                         "Intrinsics: distortion: " << DistortionSizeProblem(distortion.size()));
  for (std::size_t i = 0; i < distortion.size(); ++i) {
    AUTODRIVE_THROW_UNLESS(std::isfinite(distortion[i]), "Intrinsics: distortion["
                                                             << i << "] must be finite, got "
                                                             << distortion[i]);
  }
}

Eigen::Matrix3d Intrinsics::CameraMatrix() const {
  Eigen::Matrix3d K;
  K << fx_px, 0.0, cx_px,  //
      0.0, fy_px, cy_px,   //
      0.0, 0.0, 1.0;
  return K;
}

std::array<double, 8> Intrinsics::DistortionCoefficients() const {
  AUTODRIVE_CHECK(distortion.size() <= 8, "distortion has " << distortion.size() << " elements");
  std::array<double, 8> k{};
  std::copy(distortion.begin(), distortion.end(), k.begin());
  return k;
}

Intrinsics IntrinsicsFromSensor(double focal_length_mm, double sensor_width_mm, int width_px,
                                int height_px) {
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(focal_length_mm) && focal_length_mm > 0.0,
      "IntrinsicsFromSensor: focal_length_mm must be finite and positive, got " << focal_length_mm);
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(sensor_width_mm) && sensor_width_mm > 0.0,
      "IntrinsicsFromSensor: sensor_width_mm must be finite and positive, got " << sensor_width_mm);
  AUTODRIVE_THROW_UNLESS(width_px > 0,
                         "IntrinsicsFromSensor: width_px must be positive, got " << width_px);
  AUTODRIVE_THROW_UNLESS(height_px > 0,
                         "IntrinsicsFromSensor: height_px must be positive, got " << height_px);
  const double f_px = focal_length_mm * static_cast<double>(width_px) / sensor_width_mm;
  Intrinsics intrinsics;
  intrinsics.width_px = width_px;
  intrinsics.height_px = height_px;
  intrinsics.fx_px = f_px;
  intrinsics.fy_px = f_px;
  intrinsics.cx_px = 0.5 * (static_cast<double>(width_px) - 1.0);
  intrinsics.cy_px = 0.5 * (static_cast<double>(height_px) - 1.0);
  return intrinsics;
}

Intrinsics PiCameraV21Intrinsics() {
  return IntrinsicsFromSensor(kPiCameraV21FocalLengthMm, kPiCameraV21SensorWidthMm, 1280, 720);
}

// --- CameraModel ---

CameraModel::CameraModel(Intrinsics intrinsics) : intrinsics_(std::move(intrinsics)) {
  intrinsics_.Validate();
  k_ = intrinsics_.DistortionCoefficients();
  max_radius_ = MaxNormalizedRadius(k_);
}

Eigen::Vector2d CameraModel::Distort(const Eigen::Vector2d& xy) const {
  return DistortWithJacobian(k_, xy).xy;
}

std::optional<Eigen::Vector2d> CameraModel::Project(const Eigen::Vector3d& p_CQ) const {
  AUTODRIVE_THROW_UNLESS(p_CQ.allFinite(),
                         "CameraModel::Project: point must be finite, got " << VectorText(p_CQ));
  if (p_CQ.z() <= kMinDepthM) {
    return std::nullopt;
  }
  const Eigen::Vector2d xy = p_CQ.head<2>() / p_CQ.z();
  if (xy.squaredNorm() > max_radius_ * max_radius_) {
    return std::nullopt;
  }
  const Eigen::Vector2d d = Distort(xy);
  return Eigen::Vector2d(intrinsics_.fx_px * d.x() + intrinsics_.cx_px,
                         intrinsics_.fy_px * d.y() + intrinsics_.cy_px);
}

std::optional<Eigen::Vector2d> CameraModel::UndistortToNormalized(
    const Eigen::Vector2d& pixel) const {
  AUTODRIVE_THROW_UNLESS(pixel.allFinite(),
                         "CameraModel::UndistortToNormalized: pixel must be "
                         "finite, got "
                             << VectorText(pixel));
  const Eigen::Vector2d target((pixel.x() - intrinsics_.cx_px) / intrinsics_.fx_px,
                               (pixel.y() - intrinsics_.cy_px) / intrinsics_.fy_px);
  const double scale = 1.0 + target.norm();
  const double max_radius_sq = max_radius_ * max_radius_;

  // Start at the distorted point, pulled inside the valid region if needed.
  Eigen::Vector2d xy = target;
  if (xy.squaredNorm() > max_radius_sq) {
    xy *= 0.5 * max_radius_ / xy.norm();
  }
  Distorted at = DistortWithJacobian(k_, xy);
  double error = (at.xy - target).norm();
  for (int i = 0; i < kMaxUndistortIterations && error > kUndistortStopResidual * scale; ++i) {
    const double det = at.jacobian.determinant();
    if (!std::isfinite(det) || det == 0.0) {
      break;
    }
    const Eigen::Vector2d step = at.jacobian.inverse() * (at.xy - target);
    // Damped Newton: halve the step until it reduces the residual inside the valid region.
    bool improved = false;
    double t = 1.0;
    for (int h = 0; h < kMaxStepHalvings && !improved; ++h, t *= 0.5) {
      const Eigen::Vector2d candidate = xy - t * step;
      if (candidate.squaredNorm() > max_radius_sq) {
        continue;
      }
      Distorted next = DistortWithJacobian(k_, candidate);
      const double next_error = (next.xy - target).norm();
      if (next_error < error) {
        xy = candidate;
        at = next;
        error = next_error;
        improved = true;
      }
    }
    if (!improved) {
      break;  // No step reduces the residual any more: rounding level, or no solution.
    }
  }
  if (!(error <= kUndistortAcceptResidual * scale) || xy.squaredNorm() > max_radius_sq) {
    return std::nullopt;
  }
  return xy;
}

std::optional<Eigen::Vector3d> CameraModel::Unproject(const Eigen::Vector2d& pixel) const {
  const std::optional<Eigen::Vector2d> xy = UndistortToNormalized(pixel);
  if (!xy) {
    return std::nullopt;
  }
  return Eigen::Vector3d(xy->x(), xy->y(), 1.0).normalized();
}

bool CameraModel::IsInImage(const Eigen::Vector2d& pixel) const {
  return pixel.x() >= -0.5 && pixel.x() < static_cast<double>(intrinsics_.width_px) - 0.5 &&
         pixel.y() >= -0.5 && pixel.y() < static_cast<double>(intrinsics_.height_px) - 0.5;
}

FieldOfView CameraModel::fov() const {
  const double w = static_cast<double>(intrinsics_.width_px);
  const double h = static_cast<double>(intrinsics_.height_px);
  const auto normalized = [this](const Eigen::Vector2d& pixel) {
    const std::optional<Eigen::Vector2d> xy = UndistortToNormalized(pixel);
    AUTODRIVE_THROW_UNLESS(xy.has_value(), "CameraModel::fov: the image edge at pixel "
                                               << VectorText(pixel)
                                               << " lies beyond the distortion model's valid "
                                                  "region (max normalised radius "
                                               << max_radius_ << ")");
    return *xy;
  };
  const Eigen::Vector2d left = normalized({-0.5, intrinsics_.cy_px});
  const Eigen::Vector2d right = normalized({w - 0.5, intrinsics_.cy_px});
  const Eigen::Vector2d top = normalized({intrinsics_.cx_px, -0.5});
  const Eigen::Vector2d bottom = normalized({intrinsics_.cx_px, h - 0.5});
  return {.horizontal_rad = std::atan(right.x()) - std::atan(left.x()),
          .vertical_rad = std::atan(bottom.y()) - std::atan(top.y())};
}

// --- Extrinsics ---

Eigen::Matrix3d RotationBodyFromOptical() {
  Eigen::Matrix3d R_BC;
  // Columns: C's x (right) = -y_B, C's y (down) = -z_B, C's z (forward) = x_B.
  R_BC << 0.0, 0.0, 1.0,  //
      -1.0, 0.0, 0.0,     //
      0.0, -1.0, 0.0;
  return R_BC;
}

Eigen::Isometry3d CameraPoseFromMount(const Eigen::Vector3d& p_PB_m, const RollPitchYaw& rpy_PB) {
  AUTODRIVE_THROW_UNLESS(p_PB_m.allFinite(), "CameraPoseFromMount: position must be finite, got "
                                                 << VectorText(p_PB_m));
  const Eigen::Matrix3d R_PB = QuaternionFromRollPitchYaw(rpy_PB).toRotationMatrix();
  Eigen::Isometry3d X_PC = Eigen::Isometry3d::Identity();
  X_PC.linear() = R_PB * RotationBodyFromOptical();
  X_PC.translation() = p_PB_m;
  return X_PC;
}

std::optional<Eigen::Vector2d> Camera::ProjectFromParent(const Eigen::Vector3d& p_PQ) const {
  AUTODRIVE_THROW_UNLESS(p_PQ.allFinite(), "Camera::ProjectFromParent (" << name
                                                                         << "): point must be "
                                                                            "finite, got "
                                                                         << VectorText(p_PQ));
  return model.Project(X_PC.inverse(Eigen::Isometry) * p_PQ);
}

std::optional<Ray> Camera::UnprojectToParent(const Eigen::Vector2d& pixel) const {
  const std::optional<Eigen::Vector3d> direction_C = model.Unproject(pixel);
  if (!direction_C) {
    return std::nullopt;
  }
  return Ray{.origin_m = X_PC.translation(), .direction = X_PC.linear() * *direction_C};
}

// --- OpenCV calibration files ---

namespace {

// Builds `FILE: KEY: message` errors for one calibration file.
class CalibrationFileErrors {
 public:
  explicit CalibrationFileErrors(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& message) const {
    throw ConfigError(file_ + ": " + key + ": " + message);
  }
  [[noreturn]] void FailFile(const std::string& message) const {
    throw ConfigError(file_ + ": " + message);
  }

 private:
  std::string file_;
};

// OpenCV's description of an exception. Its YAML parser puts the file, line and problem in
// `func` and the parsing routine in `err`, so both are given.
std::string OpenCvText(const cv::Exception& e) {
  return "OpenCV: " + e.err + (e.func.empty() ? std::string() : ": " + e.func);
}

std::string Text(double value) {
  std::ostringstream os;
  os.precision(17);
  os << value;
  return os.str();
}

cv::FileNode RequiredNode(const cv::FileStorage& fs, const std::string& key,
                          const CalibrationFileErrors& errors) {
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) {
    errors.Fail(key, "missing required key");
  }
  return node;
}

int ReadPositiveInt(const cv::FileStorage& fs, const std::string& key,
                    const CalibrationFileErrors& errors) {
  const cv::FileNode node = RequiredNode(fs, key, errors);
  if (!node.isInt()) {
    errors.Fail(key, "must be an integer number of pixels" +
                         std::string(node.isReal() ? " (got " + Text(node.real()) + ")"
                                                   : " (got a non-number)"));
  }
  const int value = static_cast<int>(node);
  if (value <= 0) {
    errors.Fail(key, "must be positive (got " + std::to_string(value) + ")");
  }
  return value;
}

// A single-channel `!!opencv-matrix` as doubles.
cv::Mat ReadMatrix(const cv::FileStorage& fs, const std::string& key,
                   const CalibrationFileErrors& errors) {
  const cv::FileNode node = RequiredNode(fs, key, errors);
  if (!node.isMap()) {
    errors.Fail(key, "must be an !!opencv-matrix with rows, cols, dt and data");
  }
  cv::Mat m;
  try {
    cv::read(node, m, cv::Mat());
  } catch (const cv::Exception& e) {
    errors.Fail(key, "not a readable !!opencv-matrix (" + OpenCvText(e) + ")");
  }
  if (m.empty()) {
    errors.Fail(key, "must be a non-empty !!opencv-matrix with rows, cols, dt and data");
  }
  if (m.channels() != 1) {
    errors.Fail(key, "must have one channel (got " + std::to_string(m.channels()) + ")");
  }
  cv::Mat m64;
  m.convertTo(m64, CV_64F);
  return m64;
}

std::string ShapeText(const cv::Mat& m) {
  return std::to_string(m.rows) + "x" + std::to_string(m.cols);
}

}  // namespace

Intrinsics LoadOpenCvCalibration(const std::filesystem::path& path) {
  const std::string file = path.string();
  const CalibrationFileErrors errors(file);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    errors.FailFile(std::string("cannot read camera calibration file (") +
                    (std::filesystem::exists(path, ec) ? "not a regular file" : "no such file") +
                    ")");
  }
  cv::FileStorage fs;
  try {
    if (!fs.open(file, cv::FileStorage::READ)) {
      errors.FailFile("cannot read camera calibration file (OpenCV could not open it)");
    }
  } catch (const cv::Exception& e) {
    errors.FailFile("cannot parse camera calibration file (" + OpenCvText(e) + ")");
  }

  Intrinsics intrinsics;
  intrinsics.width_px = ReadPositiveInt(fs, "image_width", errors);
  intrinsics.height_px = ReadPositiveInt(fs, "image_height", errors);

  const cv::Mat K = ReadMatrix(fs, "camera_matrix", errors);
  if (K.rows != 3 || K.cols != 3) {
    errors.Fail("camera_matrix", "must be 3x3 (got " + ShapeText(K) + ")");
  }
  const auto k = [&K](int r, int c) { return K.at<double>(r, c); };
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(k(r, c))) {
        errors.Fail("camera_matrix", "element (" + std::to_string(r) + ", " + std::to_string(c) +
                                         ") must be finite (got " + Text(k(r, c)) + ")");
      }
    }
  }
  if (!(k(0, 0) > 0.0)) {
    errors.Fail("camera_matrix",
                "focal length fx = element (0, 0) must be positive (got " + Text(k(0, 0)) + ")");
  }
  if (!(k(1, 1) > 0.0)) {
    errors.Fail("camera_matrix",
                "focal length fy = element (1, 1) must be positive (got " + Text(k(1, 1)) + ")");
  }
  if (k(0, 1) != 0.0) {
    errors.Fail("camera_matrix",
                "skew (element (0, 1)) is not supported; it must be 0 (got " + Text(k(0, 1)) + ")");
  }
  if (k(1, 0) != 0.0 || k(2, 0) != 0.0 || k(2, 1) != 0.0 || k(2, 2) != 1.0) {
    errors.Fail("camera_matrix", "must have the form [fx 0 cx; 0 fy cy; 0 0 1] (got row 1 [" +
                                     Text(k(1, 0)) + " ...] and row 2 [" + Text(k(2, 0)) + " " +
                                     Text(k(2, 1)) + " " + Text(k(2, 2)) + "])");
  }
  intrinsics.fx_px = k(0, 0);
  intrinsics.fy_px = k(1, 1);
  intrinsics.cx_px = k(0, 2);
  intrinsics.cy_px = k(1, 2);

  const cv::Mat D = ReadMatrix(fs, "distortion_coefficients", errors);
  if (D.rows != 1 && D.cols != 1) {
    errors.Fail("distortion_coefficients",
                "must be a 1xN or Nx1 vector (got " + ShapeText(D) + ")");
  }
  const std::size_t n = D.total();
  if (n == 0 || !IsSupportedDistortionSize(n)) {
    errors.Fail("distortion_coefficients", DistortionSizeProblem(n));
  }
  intrinsics.distortion.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double value = D.at<double>(static_cast<int>(i));
    if (!std::isfinite(value)) {
      errors.Fail("distortion_coefficients",
                  "coefficient " + std::to_string(i) + " must be finite (got " + Text(value) + ")");
    }
    intrinsics.distortion.push_back(value);
  }
  try {
    intrinsics.Validate();
  } catch (const InputError& e) {
    errors.FailFile(e.what());  // Not reached: every field was checked above.
  }
  return intrinsics;
}

void SaveOpenCvCalibration(const std::filesystem::path& path, const Intrinsics& intrinsics) {
  SaveOpenCvCalibration(path, intrinsics, [](cv::FileStorage&) {});
}

void SaveOpenCvCalibration(const std::filesystem::path& path, const Intrinsics& intrinsics,
                           const std::function<void(cv::FileStorage&)>& extra) {
  intrinsics.Validate();
  const std::string file = path.string();
  cv::Mat K(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      K.at<double>(r, c) = intrinsics.CameraMatrix()(r, c);
    }
  }
  const std::vector<double> coefficients =
      intrinsics.distortion.empty() ? std::vector<double>(5, 0.0) : intrinsics.distortion;
  cv::Mat D(static_cast<int>(coefficients.size()), 1, CV_64F);
  for (std::size_t i = 0; i < coefficients.size(); ++i) {
    D.at<double>(static_cast<int>(i)) = coefficients[i];
  }
  try {
    cv::FileStorage fs;
    if (!fs.open(file, cv::FileStorage::WRITE)) {
      throw InputError(file + ": cannot write camera calibration file (OpenCV could not open it)");
    }
    fs << "image_width" << intrinsics.width_px;
    fs << "image_height" << intrinsics.height_px;
    fs << "camera_matrix" << K;
    fs << "distortion_coefficients" << D;
    extra(fs);
    fs.release();
  } catch (const cv::Exception& e) {
    throw InputError(file + ": cannot write camera calibration file (" + OpenCvText(e) + ")");
  }
}

}  // namespace autodrive::camera
