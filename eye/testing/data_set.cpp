#include "eye/testing/data_set.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "common/geometry.h"

namespace autodrive::eye::testing {

std::vector<std::vector<std::string>> ReadCsv(const std::filesystem::path& path,
                                              const std::string& header) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, header) << path;
  std::vector<std::vector<std::string>> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    rows.push_back(f);
  }
  return rows;
}

std::map<RowKey, RowPose> ReadGroundTruth(const std::filesystem::path& data_set) {
  std::map<RowKey, RowPose> out;
  for (const auto& f :
       ReadCsv(data_set / "ground_truth.csv", "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad")) {
    EXPECT_EQ(f.size(), 7u);
    if (f.size() != 7) continue;
    out[{std::stoi(f[0]), f[2]}] = {std::stod(f[4]), std::stod(f[5]), std::stod(f[6])};
  }
  return out;
}

std::map<RowKey, RowPose> ReadLocalizedPoses(const std::filesystem::path& csv,
                                             std::map<RowKey, std::string>* cameras) {
  std::map<RowKey, RowPose> out;
  for (const auto& f : ReadCsv(csv, "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad,camera")) {
    EXPECT_EQ(f.size(), 8u);
    if (f.size() != 8) continue;
    const RowKey key{std::stoi(f[0]), f[2]};
    out[key] = {std::stod(f[4]), std::stod(f[5]), std::stod(f[6])};
    if (cameras != nullptr) (*cameras)[key] = f[7];
  }
  return out;
}

camera::Camera LoadDataSetCamera(const std::filesystem::path& data_set) {
  const camera::Intrinsics k = camera::LoadOpenCvCalibration(data_set / "camera.yaml");
  const YAML::Node pose = YAML::LoadFile((data_set / "camera_pose.yaml").string());
  Eigen::Matrix4d X = Eigen::Matrix4d::Zero();
  for (std::size_t r = 0; r < 4; ++r) {
    for (std::size_t c = 0; c < 4; ++c) {
      X(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
          pose["X_parent_optical"][r][c].as<double>();
    }
  }
  return {"c", "c", "map", camera::CameraModel(k), Eigen::Isometry3d(X)};
}

bool TagFullyVisible(const camera::Camera& cam, const RowPose& car,
                     const camera::RoofTagMount& mount, double tag_size_m, double tag_height_m) {
  const double half = tag_size_m * 10 / 8 / 2;  // tag36h11: 10 bits across, 8 inside the border
  const double tag_yaw = mount.TagYaw(car.yaw_rad);
  const auto& in = cam.model.intrinsics();
  for (int k = 0; k < 4; ++k) {
    const double sx = (k & 1) ? half : -half, sy = (k & 2) ? half : -half;
    const Eigen::Vector3d p(car.x_m + std::cos(tag_yaw) * sx - std::sin(tag_yaw) * sy,
                            car.y_m + std::sin(tag_yaw) * sx + std::cos(tag_yaw) * sy,
                            tag_height_m);
    const auto px = cam.ProjectFromParent(p);
    if (!px || px->x() < 5 || px->y() < 5 || px->x() > in.width_px - 6 ||
        px->y() > in.height_px - 6) {
      return false;
    }
  }
  return true;
}

Comparison CompareWithTruth(const std::map<RowKey, RowPose>& truth,
                            const std::map<RowKey, RowPose>& estimate,
                            const std::vector<camera::Camera>& cameras,
                            const std::map<std::string, camera::RoofTagMount>& mounts) {
  Comparison c;
  double sum_p2 = 0, sum_y2 = 0;
  for (const auto& [key, t] : truth) {
    const auto mount = mounts.find(key.second);
    bool full = false;
    for (const auto& cam : cameras) {
      full = full || TagFullyVisible(
                         cam, t, mount == mounts.end() ? camera::RoofTagMount{} : mount->second);
    }
    const auto it = estimate.find(key);
    if (full) {
      auto& [found, total] = c.localised_of_visible[key.second];
      ++total;
      if (it != estimate.end()) ++found;
    }
    if (it == estimate.end()) continue;
    const double dp = std::hypot(it->second.x_m - t.x_m, it->second.y_m - t.y_m);
    const double dy = std::abs(std::remainder(it->second.yaw_rad - t.yaw_rad, 2 * kPi));
    sum_p2 += dp * dp;
    sum_y2 += dy * dy;
    c.max_position_m = std::max(c.max_position_m, dp);
    c.max_heading_rad = std::max(c.max_heading_rad, dy);
    ++c.compared;
  }
  for (const auto& [key, e] : estimate) c.false_rows += truth.contains(key) ? 0 : 1;
  if (c.compared > 0) {
    c.rms_position_m = std::sqrt(sum_p2 / c.compared);
    c.rms_heading_rad = std::sqrt(sum_y2 / c.compared);
  }
  return c;
}

}  // namespace autodrive::eye::testing
