#include "eye/eye_config.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/camera/camera_model.h"
#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::eye {
namespace {

TEST(EyeConfig, EveryShippedCityHasAnEyeSectionThatLoadsAndRoundTrips) {
  int cities = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(test::SourceDir() / "config" / "cities")) {
    const EyeConfig config = LoadEyeConfig(entry.path());
    ++cities;
    ASSERT_FALSE(config.cameras.empty()) << entry.path();
    for (const CameraConfig& c : config.cameras) {
      // The calibration is resolved next to the city file, and exists.
      EXPECT_TRUE(std::filesystem::path(c.calibration).is_absolute());
      EXPECT_NO_THROW((void)camera::LoadOpenCvCalibration(c.calibration)) << c.calibration;
    }
    EXPECT_GE(config.reference_tags.size(), 4u) << entry.path();
    EXPECT_EQ(config::LoadString<EyeConfig>(config::SaveString(config)), config);
  }
  EXPECT_GE(cities, 2);
}

class EyeConfigErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = std::filesystem::temp_directory_path() /
            ("eye_config_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".yaml");
  }
  void TearDown() override { std::filesystem::remove(path_); }
  std::string Error(const std::string& yaml) {
    std::ofstream(path_) << yaml;
    try {
      (void)LoadEyeConfig(path_);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path path_;
};

constexpr const char* kCamera =
    "cameras: [{name: top, source: \"images:/tmp\", calibration: c.yaml}]\n";

TEST_F(EyeConfigErrors, BadFilesAreRefusedNamingWhatIsWrong) {
  EXPECT_NE(Error(std::string(kCamera) + "vehicles: [{name: nigel_1, tag_id: 1, colour: red}]\n")
                .find("unknown key"),
            std::string::npos);
  EXPECT_NE(Error(std::string(kCamera) + "vehicles: [{name: car_1, tag_id: 1}]\n").find("car_1"),
            std::string::npos);
  EXPECT_NE(Error(std::string(kCamera) +
                  "vehicles: [{name: nigel_1, tag_id: 5}]\nreference_tags: [{id: 5, x_m: 0, "
                  "y_m: 0}]\n")
                .find("id 5 is another tag's too"),
            std::string::npos);
  EXPECT_NE(Error("cameras: [{name: top, source: \"webcam:0\", calibration: c.yaml}]\n"
                  "vehicles: []\n")
                .find("source: expected topic:NAME"),
            std::string::npos);
  EXPECT_NE(Error(std::string(kCamera) + "detector: {family: tag99h1}\nvehicles: []\n")
                .find("unknown AprilTag family \"tag99h1\""),
            std::string::npos);
  EXPECT_NE(
      Error(std::string(kCamera) + "vehicles: [{name: nigel_1, tag_id: 600}]\n").find("ids 0..586"),
      std::string::npos);
  EXPECT_NE(Error("vehicles: []\n").find("cameras"), std::string::npos);
}

TEST_F(EyeConfigErrors, ATagsMountingIsReadRoundTripsAndIsCheckedLikeEveryKey) {
  std::ofstream(path_)
      << kCamera
      << "vehicles:\n  - {name: nigel_1, tag_id: 1, tag_yaw_deg: 90, "
         "tag_ahead_m: 0.05, tag_left_m: -0.012}\n  - {name: nigel_2, tag_id: 2}\n";
  const EyeConfig config = LoadEyeConfig(path_);
  EXPECT_EQ(config.vehicles[0].mount, (camera::RoofTagMount{90.0, 0.05, -0.012}));
  // Absent keys: today's meaning (top to the front, over the middle of Nigel's body).
  EXPECT_EQ(config.vehicles[1].mount, (camera::RoofTagMount{0.0, 0.07077, 0.0}));
  EXPECT_EQ(config::LoadString<EyeConfig>(config::SaveString(config)), config);
  EXPECT_EQ(
      Error(std::string(kCamera) + "vehicles:\n  - {name: nigel_1, tag_id: 1, tag_yaw_deg: 400}\n"),
      path_.string() +
          ":3:45: vehicles[0].tag_yaw_deg: out of range (got 400; expected a "
          "value in [-360.0, 360.0])");
  EXPECT_NE(Error(std::string(kCamera) + "vehicles: [{name: nigel_1, tag_id: 1, tag_lef_m: 0.1}]\n")
                .find("vehicles[0].tag_lef_m: unknown key (did you mean tag_left_m?"),
            std::string::npos);
  EXPECT_NE(Error(std::string(kCamera) + "vehicles: [{name: nigel_1, tag_id: 1, tag_ahead_m: 6}]\n")
                .find("vehicles[0].tag_ahead_m: out of range (got 6; expected a value in [-5.0, "
                      "5.0])"),
            std::string::npos);
}

TEST_F(EyeConfigErrors, FilesAreResolvedNextToTheConfiguration) {
  std::ofstream(path_) << kCamera << "vehicles: []\n";
  const EyeConfig config = LoadEyeConfig(path_);
  EXPECT_EQ(config.cameras[0].calibration, (path_.parent_path() / "c.yaml").string());
  EXPECT_EQ(config.cameras[0].source, "images:/tmp");
}

}  // namespace
}  // namespace autodrive::eye
