#include "eye/tag_pose.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

namespace autodrive::eye {

std::optional<PlanarTagPose> LocateHorizontalTag(const camera::Camera& camera,
                                                 const TagDetection& detection, double size_m,
                                                 double height_m, double corner_sigma_px) {
  const camera::Intrinsics& in = camera.model.intrinsics();
  const double f = std::sqrt(in.fx_px * in.fy_px);
  const Eigen::Matrix3d R_MC = camera.X_PC.linear();
  const Eigen::Vector3d p_MC = camera.X_PC.translation();
  const Eigen::Matrix3d R_CM = R_MC.transpose();
  const Eigen::Vector3d p_CM = -R_CM * p_MC;
  const std::array<Eigen::Vector3d, 4> model = TagCorners(size_m);

  // The corners' undistorted normalised coordinates, and where their rays meet the plane.
  std::array<Eigen::Vector2d, 4> m;
  std::array<Eigen::Vector2d, 4> hit;
  for (std::size_t k = 0; k < 4; ++k) {
    const auto xy = camera.model.UndistortToNormalized(detection.corners_px[k]);
    if (!xy) return std::nullopt;
    m[k] = *xy;
    const Eigen::Vector3d d = R_MC * Eigen::Vector3d(xy->x(), xy->y(), 1.0);
    if (std::abs(d.z()) < 1e-12) return std::nullopt;
    const double t = (height_m - p_MC.z()) / d.z();
    if (!(t > 0)) return std::nullopt;
    hit[k] = (p_MC + t * d).head<2>();
  }
  // A rigid fit of the square's corners to the hits (2-D Procrustes).
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const auto& h : hit) centre += h / 4.0;
  double s_dot = 0, s_cross = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector2d a = model[k].head<2>();
    const Eigen::Vector2d b = hit[k] - centre;
    s_dot += a.dot(b);
    s_cross += a.x() * b.y() - a.y() * b.x();
  }
  Eigen::Vector3d s(centre.x(), centre.y(), std::atan2(s_cross, s_dot));

  // Gauss-Newton on the reprojection error in undistorted pixels (normalised * f).
  Eigen::Matrix<double, 8, 3> J;
  Eigen::Matrix<double, 8, 1> r;
  const auto evaluate = [&](const Eigen::Vector3d& x) {
    const double c = std::cos(x.z()), sn = std::sin(x.z());
    for (std::size_t k = 0; k < 4; ++k) {
      const Eigen::Vector2d a = model[k].head<2>();
      const Eigen::Vector3d p_M(x.x() + c * a.x() - sn * a.y(), x.y() + sn * a.x() + c * a.y(),
                                height_m);
      const Eigen::Vector3d dp_dyaw(-sn * a.x() - c * a.y(), c * a.x() - sn * a.y(), 0.0);
      const Eigen::Vector3d q = R_CM * p_M + p_CM;
      if (q.z() <= 1e-9) return false;
      const double iz = 1.0 / q.z();
      Eigen::Matrix<double, 2, 3> dproj;
      dproj << iz, 0, -q.x() * iz * iz, 0, iz, -q.y() * iz * iz;
      Eigen::Matrix3d dq;
      dq.col(0) = R_CM.col(0);
      dq.col(1) = R_CM.col(1);
      dq.col(2) = R_CM * dp_dyaw;
      const auto row = static_cast<Eigen::Index>(2 * k);
      J.block<2, 3>(row, 0) = f * dproj * dq;
      r.segment<2>(row) = f * (Eigen::Vector2d(q.x() * iz, q.y() * iz) - m[k]);
    }
    return true;
  };
  for (int iteration = 0; iteration < 10; ++iteration) {
    if (!evaluate(s)) return std::nullopt;
    const Eigen::Vector3d step = (J.transpose() * J).ldlt().solve(-J.transpose() * r);
    s += step;
    if (step.head<2>().norm() < 1e-9 && std::abs(step.z()) < 1e-9) break;
  }
  if (!evaluate(s)) return std::nullopt;
  PlanarTagPose pose;
  pose.p_M = s.head<2>();
  pose.yaw_rad = std::remainder(s.z(), 2 * kPi);
  pose.rms_px = std::sqrt(r.squaredNorm() / 4.0);
  pose.covariance = corner_sigma_px * corner_sigma_px * (J.transpose() * J).inverse();
  return pose;
}

}  // namespace autodrive::eye
