// The parking agent's tunables file: the shipped one says what the agent does when given none,
// and a file edited by hand is refused on the key it got wrong.
#include "examples/parking/parking_config.h"

#include <gtest/gtest.h>

#include "common/config.h"
#include "common/test_support.h"

namespace autodrive::examples {
namespace {

TEST(ParkingConfig, TheShippedFileIsTheAgentsDefaults) {
  const ParkingConfig shipped =
      LoadParkingConfig((test::SourceDir() / "examples/parking/parking.yaml").string());
  EXPECT_EQ(config::SaveString(shipped), config::SaveString(ParkingConfig{}));
  EXPECT_EQ(shipped.localiser.mapping_scans, 10);
  EXPECT_EQ(shipped.localiser.filter.max_range_m, 6.0);
}

TEST(ParkingConfig, APartialFileKeepsTheRest) {
  const test::TempDir dir("parking_config");
  const auto file = dir.path() / "tuning.yaml";
  config::WriteFile(file,
                    "planner:\n  margin_m: 0.05\nlocaliser:\n  filter:\n    hit_sigma_m: 0.03\n");
  const ParkingConfig c = LoadParkingConfig(file.string());
  EXPECT_EQ(c.planner.margin_m, 0.05);
  EXPECT_EQ(c.localiser.filter.hit_sigma_m, 0.03);
  EXPECT_EQ(c.planner.step_m, ParkingConfig{}.planner.step_m);
  EXPECT_EQ(c.localiser.filter.beam_skip_distance_m, 0.05);  // the agent's, not the filter's 0
  EXPECT_EQ(c.arrival.corrections, 2);
}

TEST(ParkingConfig, AFileEditedByHandIsRefusedOnItsKey) {
  const test::TempDir dir("parking_config_bad");
  const auto file = dir.path() / "tuning.yaml";
  const auto refused = [&](const std::string& text) {
    config::WriteFile(file, text);
    try {
      (void)LoadParkingConfig(file.string());
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  std::string why = refused("planner:\n  margn_m: 0.05\n");
  EXPECT_NE(why.find("tuning.yaml:2"), std::string::npos) << why;
  EXPECT_NE(why.find("margn_m"), std::string::npos) << why;
  why = refused("tracker:\n  lookahead_m: -1\n");
  EXPECT_NE(why.find("tracker.lookahead_m"), std::string::npos) << why;
  why = refused("localiser:\n  filter:\n    min_particles: 500\n    max_particles: 100\n");
  EXPECT_NE(why.find("max_particles must be at least min_particles"), std::string::npos) << why;
  why = refused("arrival:\n  corrections: two\n");
  EXPECT_NE(why.find("arrival.corrections"), std::string::npos) << why;
}

}  // namespace
}  // namespace autodrive::examples
