#include "common/camera/roof_tag.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::camera {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = kPi / 180.0;

// The tag's top (T's y) and right edge (T's x) in the car's frame, for each mounting of the
// picture in words (roof_tag.h, docs/eye.md).
TEST(RoofTagMount, TheTagsTopFacesTheCarsFrontTurnedByTheYaw) {
  struct Case {
    double yaw_deg;
    Eigen::Vector2d top_V;    // where the tag's top points, in V
    Eigen::Vector2d right_V;  // where the bitmap's right edge points, in V
  };
  for (const Case& c :
       {Case{0, {1, 0}, {0, -1}}, Case{90, {0, 1}, {1, 0}}, Case{180, {-1, 0}, {0, 1}},
        Case{270, {0, -1}, {-1, 0}}, Case{-90, {0, -1}, {-1, 0}}}) {
    RoofTagMount mount;
    mount.yaw_deg = c.yaw_deg;
    const Eigen::Matrix2d R_VT = mount.X_VT().rotation_matrix();
    EXPECT_TRUE((R_VT * Eigen::Vector2d::UnitY()).isApprox(c.top_V, 1e-12)) << c.yaw_deg;
    EXPECT_TRUE((R_VT * Eigen::Vector2d::UnitX()).isApprox(c.right_V, 1e-12)) << c.yaw_deg;
  }
}

TEST(RoofTagMount, TheCarsHeadingAndTheTagsYawConvertBothWays) {
  RoofTagMount mount;
  // The default: the car's yaw is the tag's + 90°, the tag's centre over Nigel's body.
  EXPECT_NEAR(mount.VehicleYaw(0.0), kPi / 2, 1e-12);
  EXPECT_NEAR(mount.TagYaw(kPi / 2), 0.0, 1e-12);
  EXPECT_EQ(mount.p_VT(), Eigen::Vector2d(0.07077, 0.0));
  for (double yaw_deg : {-90.0, 0.0, 37.5, 90.0, 180.0, 270.0}) {
    mount.yaw_deg = yaw_deg;
    for (double car = -3.0; car < 3.2; car += 0.7) {
      const double tag = mount.TagYaw(car);
      EXPECT_NEAR(WrapAngle(tag - car - (yaw_deg - 90) * kDeg), 0.0, 1e-12);
      EXPECT_NEAR(WrapAngle(mount.VehicleYaw(tag) - car), 0.0, 1e-12);
    }
  }
  // The tag's pose in the map is the car's pose composed with X_VT.
  mount = {90.0, 0.05, 0.02};
  const RigidTransform2 X_MV = RigidTransform2::FromXyYaw(1.0, 2.0, 0.3);
  const RigidTransform2 X_MT = X_MV * mount.X_VT();
  EXPECT_NEAR(WrapAngle(X_MT.yaw() - mount.TagYaw(0.3)), 0.0, 1e-12);
  EXPECT_TRUE(X_MT.translation().isApprox(
      Eigen::Vector2d(1.0 + 0.05 * std::cos(0.3) - 0.02 * std::sin(0.3),
                      2.0 + 0.05 * std::sin(0.3) + 0.02 * std::cos(0.3)),
      1e-12));
}

class CityRoofTagMounts : public ::testing::Test {
 protected:
  std::filesystem::path Write(const std::string& yaml) {
    const auto file = dir_.path() / "city.yaml";
    std::ofstream(file) << yaml;
    return file;
  }
  test::TempDir dir_{"roof_tag"};
};

TEST_F(CityRoofTagMounts, AreReadFromTheEyesVehiclesWithTheirDefaults) {
  const auto file = Write(
      "name: t\nmap: m.yaml\n"
      "eye:\n"
      "  cameras: [{name: top, source: \"topic:top\", calibration: c.yaml}]\n"
      "  vehicles:\n"
      "    - {name: nigel_1, tag_id: 1, tag_yaw_deg: 90, tag_left_m: -0.01}\n"
      "    - {name: nigel_2, tag_id: 2, tag_size_m: 0.05}\n");
  const std::vector<DeclaredRoofTagMount> mounts = LoadCityRoofTagMounts(file);
  ASSERT_EQ(mounts.size(), 2u);
  EXPECT_EQ(mounts[0].vehicle, "nigel_1");
  EXPECT_EQ(mounts[0].mount, (RoofTagMount{90.0, 0.07077, -0.01}));
  EXPECT_EQ(mounts[0].where, file.string() + ":6: eye.vehicles[0]");
  EXPECT_EQ(mounts[1].vehicle, "nigel_2");
  EXPECT_EQ(mounts[1].mount, RoofTagMount{});
  // No eye section, or one without vehicles: nothing declared.
  EXPECT_TRUE(LoadCityRoofTagMounts(Write("name: t\nmap: m.yaml\n")).empty());
  EXPECT_TRUE(LoadCityRoofTagMounts(Write("name: t\nmap: m.yaml\neye: {}\n")).empty());
}

TEST_F(CityRoofTagMounts, ABadValueIsRefusedWithFileLineAndKey) {
  const auto file = Write(
      "name: t\nmap: m.yaml\neye:\n  vehicles:\n"
      "    - {name: nigel_1, tag_yaw_deg: 400}\n");
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)LoadCityRoofTagMounts(file); }),
              HasSubstr(file.string() + ":5:36: eye.vehicles[0].tag_yaw_deg: out of range (got "
                                        "400; expected a value in [-360.0, 360.0])"));
  const auto unnamed = Write("name: t\nmap: m.yaml\neye:\n  vehicles:\n    - {tag_left_m: 0.1}\n");
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] { (void)LoadCityRoofTagMounts(unnamed); }),
              HasSubstr("eye.vehicles[0].name: missing required key"));
}

}  // namespace
}  // namespace autodrive::camera
