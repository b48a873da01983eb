// A city file's sim section as the simulator reads it: the cars' roof tag mountings, declared
// once for the simulator and the Eye in the Eye's entries.
#include "vehicle_sim/sim_config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::vehicle_sim {
namespace {

using ::testing::HasSubstr;

class SimCityMounting : public ::testing::Test {
 protected:
  // A city with two cars in the simulator; `look` is nigel_1's look, `eye` the Eye's entries.
  std::string Write(const std::string& look, const std::string& eye_vehicles) {
    const auto file = dir_.path() / "city.yaml";
    std::ofstream(file) << "name: t\nmap: m.yaml\nintersections: []\nsim:\n  vehicles:\n"
                        << "    - {name: nigel_1, look: " << look << "}\n"
                        << "    - {name: nigel_2}\n"
                        << "eye:\n  cameras: [{name: top, source: \"topic:top\", calibration: "
                           "c.yaml}]\n  vehicles:\n"
                        << eye_vehicles;
    return file.string();
  }
  test::TempDir dir_{"sim_config"};
};

TEST_F(SimCityMounting, ACarTheEyeListsGetsTheEyesMountingOthersTheirOwnOrTheDefault) {
  const SimCity city = LoadSimCity(
      Write("{}", "    - {name: nigel_1, tag_id: 1, tag_yaw_deg: 90, tag_left_m: 0.015}\n"));
  ASSERT_EQ(city.sim.vehicles.size(), 2u);
  const VehicleLook one = EffectiveLook(city.sim, 0);
  EXPECT_EQ(one.tag_mount, (camera::RoofTagMount{90.0, 0.07077, 0.015}));
  // Not listed by the Eye: its own look, with the body's middle as the default place.
  const VehicleLook two = EffectiveLook(city.sim, 1);
  EXPECT_EQ(two.tag_mount.yaw_deg, 0.0);
  EXPECT_EQ(two.tag_mount.ahead_m, city.sim.vehicles[1].params.body_centre_ahead_of_rear_axle_m);
  EXPECT_EQ(two.tag_mount.left_m, 0.0);
  // Without an eye section the look's keys are the mounting.
  const auto file = dir_.path() / "sim_only.yaml";
  std::ofstream(file) << "name: t\nmap: m.yaml\nsim:\n  vehicles:\n"
                      << "    - {name: nigel_1, look: {tag_yaw_deg: -90, tag_ahead_m: 0.05}}\n";
  EXPECT_EQ(EffectiveLook(LoadSimCity(file.string()).sim, 0).tag_mount,
            (camera::RoofTagMount{-90.0, 0.05, 0.0}));
}

TEST_F(SimCityMounting, AMountingDeclaredInBothPlacesIsRefusedNamingThem) {
  const std::string file = Write("{tag_yaw_deg: 90}",
                                 "    - {name: nigel_2, tag_id: 2}\n    - {name: nigel_1, "
                                 "tag_id: 1, tag_yaw_deg: 90}\n");
  EXPECT_EQ(test::ErrorMessage<ConfigError>([&] { (void)LoadSimCity(file); }),
            file +
                ":6: sim.vehicles[0].look: nigel_1's roof tag mounting (tag_yaw_deg, "
                "tag_ahead_m, tag_left_m) is declared by the Eye's entry too (" +
                file +
                ":12: eye.vehicles[1]); declare it once, there: the simulator draws the tag "
                "where the Eye expects it");
  // A bad value in the Eye's entry is refused by the simulator too, where it is.
  EXPECT_THAT(test::ErrorMessage<ConfigError>([&] {
                (void)LoadSimCity(Write("{}", "    - {name: nigel_1, tag_left_m: nine}\n"));
              }),
              HasSubstr("eye.vehicles[0].tag_left_m: wrong type"));
}

}  // namespace
}  // namespace autodrive::vehicle_sim
