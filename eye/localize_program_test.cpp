// The Eye's programs run as a lab runs them, as processes: frames rendered by the simulator
// (`autodrive-sim render`) or drawn here, localised by `autodrive-eye localize` (and `run`),
// compared with the ground truth from the files alone. Roof tags turned on the roof, corrupt
// frames, and the steps of docs/tutorials/mount-a-roof-tag.md.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/camera_model.h"
#include "common/camera/roof_tag.h"
#include "common/config.h"
#include "common/test_support.h"
#include "eye/eye_config.h"
#include "eye/registration.h"
#include "eye/testing/data_set.h"
#include "eye/testing/programs.h"
#include "eye/testing/synthetic_scene.h"

namespace autodrive::eye {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::ProgramOutput;
using testing::ProgramPath;
using testing::RowKey;
using testing::RowPose;
using testing::RunProgram;

std::string Source(const std::string& rel) { return (test::SourceDir() / rel).string(); }

// The tag_mounting events `localize` printed: the car, the frame time and the turn measured.
struct MountingEvent {
  double stamp_s = 0.0;
  std::optional<double> turn_deg;
  std::string line;
};
std::map<std::string, std::vector<MountingEvent>> MountingEvents(const std::string& output) {
  static const std::regex event(
      R"(localize: event at ([0-9.]+) s: tag_mounting (nigel_[0-9]+): (.*))");
  static const std::regex turn(R"(differs from the car's motion by (-?[0-9.]+)°)");
  std::map<std::string, std::vector<MountingEvent>> out;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (!std::regex_match(line, m, event)) continue;
    MountingEvent e{std::stod(m[1]), std::nullopt, line};
    std::smatch t;
    const std::string text = m[3];
    if (std::regex_search(text, t, turn)) e.turn_deg = std::stod(t[1]);
    out[m[2]].push_back(e);
  }
  return out;
}

// --- Roof tags turned on the roof, rendered by the simulator ---

struct Mounted {
  std::string name;
  int id;
  camera::RoofTagMount mount;
  double expected_turn_deg;  // what the Eye should find when the mounting is not configured
};

TEST(TurnedRoofTags, AreLocalisedWhenConfiguredAndRaiseTheMountingEventWithinTwoSecondsWhenNot) {
  const test::TempDir dir("eye_turned_tags");
  const std::vector<Mounted> cars{{"nigel_1", 1, {90.0, 0.07077, 0.0}, 90.0},
                                  {"nigel_2", 2, {180.0, 0.07077, 0.01}, 180.0},
                                  {"nigel_3", 3, {270.0, 0.09, 0.0}, -90.0},
                                  {"nigel_4", 4, {}, 0.0}};
  constexpr double kRateHz = 15.0;
  const fs::path set = dir.path() / "frames";
  // The Eye's configuration: the frames, the cars (with their mountings or without), the
  // reference tags on the ground.
  const auto eye_config = [&](bool with_mountings) {
    std::string text = fmt::format(
        "cameras:\n  - {{name: overhead, source: \"images:{}\", calibration: {}, rate_hz: {}}}\n"
        "vehicles:\n",
        set.string(), (set / "camera.yaml").string(), kRateHz);
    for (const Mounted& c : cars) {
      text += with_mountings ? fmt::format(
                                   "  - {{name: {}, tag_id: {}, tag_yaw_deg: {}, "
                                   "tag_ahead_m: {}, tag_left_m: {}}}\n",
                                   c.name, c.id, c.mount.yaw_deg, c.mount.ahead_m, c.mount.left_m)
                             : fmt::format("  - {{name: {}, tag_id: {}}}\n", c.name, c.id);
    }
    return text +
           "reference_tags:\n  - {id: 100, x_m: 0.5, y_m: 0.5}\n  - {id: 101, x_m: 4.5, y_m: 4.5}\n"
           "  - {id: 102, x_m: 4.5, y_m: 0.5}\n  - {id: 103, x_m: 0.5, y_m: 4.5}\n";
  };
  // The city: the Driving School, four cars, an overhead camera with noise and blur, and the
  // Eye's section with the cars' mountings, which the simulator draws them by (one
  // declaration for both).
  std::string sim_vehicles;
  for (const Mounted& c : cars) sim_vehicles += fmt::format("    - {{name: {}}}\n", c.name);
  const fs::path city = dir.path() / "city.yaml";
  std::ofstream(city) << "name: turned_tags\nmap: " << Source("config/maps/driving_school.yaml")
                      << "\nintersections: []\nsim:\n  seed: 1\n  vehicles:\n"
                      << sim_vehicles
                      << "  cameras:\n    - name: overhead\n      rate_hz: " << kRateHz
                      << "\n      lens: {width_px: 1920, height_px: 1080, focal_length_mm: 1.2, "
                         "sensor_width_mm: 3.68, distortion: [-0.05, 0.01, 0.0, 0.0]}\n"
                         "      mount: {x_m: 2.5, y_m: 2.5, z_m: 3.0, pitch_rad: 1.5708, "
                         "yaw_rad: 1.5708}\n"
                         "      film: {noise_sigma: 3.0, blur_sigma_px: 0.5, exposure_time_s: "
                         "0.005}\n  ground_tags:\n    - {tag: {id: 100}, x_m: 0.5, y_m: 0.5}\n"
                         "    - {tag: {id: 101}, x_m: 4.5, y_m: 4.5}\n    - {tag: {id: 102}, "
                         "x_m: 4.5, y_m: 0.5}\n    - {tag: {id: 103}, x_m: 0.5, y_m: 4.5}\n"
                      << "eye:\n"
                      << std::regex_replace(eye_config(true), std::regex("(^|\n)(.)"), "$1  $2");
  // The same Eye without the mountings: what a lab has before it measures them.
  const fs::path plain = dir.path() / "eye_plain.yaml";
  std::ofstream(plain) << eye_config(false);

  const ProgramOutput render =
      RunProgram({ProgramPath("autodrive-sim"), "render", "--city", city.string(), "--camera",
                  "overhead", "--duration", "6", "--out", set.string()});
  ASSERT_EQ(render.code, 0) << render.text;
  const std::map<RowKey, RowPose> truth = testing::ReadGroundTruth(set);
  ASSERT_FALSE(truth.empty());

  // Configured: every car localised in every frame it is wholly in view, to the ground truth.
  const fs::path poses = dir.path() / "poses.csv";
  const ProgramOutput configured = RunProgram(
      {ProgramPath("autodrive-eye"), "localize", "--config", city.string(), "--out", poses});
  ASSERT_EQ(configured.code, 0) << configured.text;
  std::cout << configured.text;
  std::map<std::string, camera::RoofTagMount> mounts;
  for (const Mounted& c : cars) mounts[c.name] = c.mount;
  const testing::Comparison result = testing::CompareWithTruth(
      truth, testing::ReadLocalizedPoses(poses), {testing::LoadDataSetCamera(set)}, mounts);
  std::cout << fmt::format(
      "[ measured ] turned tags, configured: {} poses; position RMS {:.2f} mm (max {:.2f}), "
      "heading RMS {:.3f} deg (max {:.3f})\n",
      result.compared, result.rms_position_m * 1e3, result.max_position_m * 1e3,
      result.rms_heading_rad * 180 / kPi, result.max_heading_rad * 180 / kPi);
  ASSERT_EQ(result.localised_of_visible.size(), cars.size());
  for (const auto& [car, counts] : result.localised_of_visible) {
    const auto [found, total] = counts;
    std::cout << fmt::format("[ measured ] {}: localised in {} of {} frames in full view\n", car,
                             found, total);
    EXPECT_GE(total, 80) << car;
    EXPECT_GE(found, 0.99 * total) << car;
  }
  EXPECT_EQ(result.false_rows, 0);
  EXPECT_LE(result.rms_position_m, 0.002);
  EXPECT_LE(result.rms_heading_rad, 0.3 * kPi / 180);
  EXPECT_TRUE(MountingEvents(configured.text).empty()) << configured.text;

  // Not configured: the event for each turned tag, within 2 s of the car starting to move,
  // with the turn; none for the car whose tag is mounted the default way.
  const ProgramOutput unconfigured =
      RunProgram({ProgramPath("autodrive-eye"), "localize", "--config", plain.string(), "--out",
                  (dir.path() / "poses_plain.csv").string()});
  ASSERT_EQ(unconfigured.code, 0) << unconfigured.text;
  const auto events = MountingEvents(unconfigured.text);
  for (const Mounted& c : cars) {
    // When it starts to move: 1 cm from where it was in the first frame.
    double moving_s = -1;
    const RowPose start = truth.at({0, c.name});
    for (int frame = 0; truth.contains({frame, c.name}); ++frame) {
      const RowPose p = truth.at({frame, c.name});
      if (std::hypot(p.x_m - start.x_m, p.y_m - start.y_m) >= 0.01) {
        moving_s = frame / kRateHz;
        break;
      }
    }
    ASSERT_GE(moving_s, 0.0) << c.name << " does not move";
    const auto it = events.find(c.name);
    if (c.expected_turn_deg == 0.0) {
      EXPECT_EQ(it, events.end()) << it->second.front().line;
      continue;
    }
    ASSERT_NE(it, events.end()) << c.name << ": no tag_mounting event in\n" << unconfigured.text;
    const MountingEvent& e = it->second.front();
    std::cout << fmt::format(
        "[ measured ] {} (tag turned {}°, not configured): {:.2f} s after it "
        "started moving: {}\n",
        c.name, c.mount.yaw_deg, e.stamp_s - moving_s, e.line);
    EXPECT_LE(e.stamp_s, moving_s + 2.0) << e.line;
    ASSERT_TRUE(e.turn_deg.has_value()) << e.line;
    EXPECT_LE(std::abs(std::remainder(*e.turn_deg - c.expected_turn_deg, 360.0)), 5.0) << e.line;
    EXPECT_EQ(it->second.size(), 1u) << "once per episode";
  }
}

// --- Unreadable frames ---

// A folder of 30 frames of a car driving, drawn through a camera whose pose the Eye is given;
// frame 15 corrupt (a PNG cut short). Returns the Eye's configuration file.
fs::path WriteFramesWithACorruptOne(const fs::path& dir) {
  const camera::Camera cam = testing::OverheadCamera(2.5, 2.5, 3.0, 700.0, 960, 540);
  fs::create_directories(dir / "frames");
  camera::SaveOpenCvCalibration(dir / "camera.yaml", cam.model.intrinsics());
  Registration r;
  r.X_MC = cam.X_PC;
  SavePose(dir / "pose.yaml", "overhead", "overhead", r);
  for (int i = 0; i < 30; ++i) {
    const double x = 1.5 + 0.2 * i / 30.0;
    const cv::Mat image = testing::DrawScene(
        cam, {{"tag36h11", 1, 0.0762, testing::FlatTagPose(x, 2.0, 0.257, -kPi / 2)}});
    const fs::path file = dir / "frames" / fmt::format("frame_{:06d}.png", i);
    EXPECT_TRUE(cv::imwrite(file.string(), image));
    if (i == 15) fs::resize_file(file, 200);
  }
  const fs::path config = dir / "eye.yaml";
  std::ofstream(config) << "cameras:\n  - {name: overhead, source: \"images:"
                        << (dir / "frames").string() << "\", calibration: camera.yaml, pose: "
                        << "pose.yaml, rate_hz: 30}\nvehicles:\n  - {name: nigel_1, tag_id: 1}\n";
  return config;
}

std::vector<int> FramesIn(const fs::path& csv) {
  std::vector<int> frames;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) frames.push_back(std::stoi(line.substr(0, line.find(','))));
  return frames;
}

TEST(LocalizeProgram, SkipsACorruptFrameNamingItAndWithStrictStopsThereLeavingNoCompleteFile) {
  const test::TempDir dir("eye_corrupt_frame");
  const fs::path config = WriteFramesWithACorruptOne(dir.path());
  const fs::path out = dir.path() / "poses.csv";
  const ProgramOutput run =
      RunProgram({ProgramPath("autodrive-eye"), "localize", "--config", config, "--out", out});
  EXPECT_EQ(run.code, 0) << run.text;
  EXPECT_THAT(run.text, HasSubstr("localize: warning: camera overhead: frame_000015.png skipped: "
                                  "not an image OpenCV can read"));
  EXPECT_THAT(run.text, HasSubstr("localize: summary: 29 frames read, 1 skipped "
                                  "(frame_000015.png), 0.97 cars localised per frame "
                                  "(nigel_1 29)"));
  ASSERT_TRUE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".partial"));
  std::vector<int> expected;
  for (int i = 0; i < 30; ++i) {
    if (i != 15) expected.push_back(i);
  }
  EXPECT_EQ(FramesIn(out), expected);

  // --strict: stops at it, non-zero; the older poses.csv is gone and the partial file has the
  // frames before it.
  const ProgramOutput strict = RunProgram(
      {ProgramPath("autodrive-eye"), "localize", "--config", config, "--out", out, "--strict"});
  EXPECT_EQ(strict.code, 1) << strict.text;
  EXPECT_THAT(strict.text, HasSubstr("camera overhead: frame_000015.png: unreadable frame (not an "
                                     "image OpenCV can read"));
  EXPECT_THAT(strict.text, HasSubstr("stopped there (--strict)"));
  EXPECT_THAT(strict.text, ::testing::Not(HasSubstr("localize: summary:")));
  EXPECT_FALSE(fs::exists(out));
  ASSERT_TRUE(fs::exists(out.string() + ".partial"));
  EXPECT_EQ(FramesIn(out.string() + ".partial"),
            std::vector<int>(expected.begin(), expected.begin() + 15));
}

TEST(RunCommand, SkipsAndCountsAnUnreadableFrameOfItsFiles) {
  const test::TempDir dir("eye_run_corrupt_frame");
  const fs::path config = WriteFramesWithACorruptOne(dir.path());
  const ProgramOutput run =
      RunProgram({ProgramPath("autodrive-eye"), "run", "--config", config, "--duration", "60",
                  "--partition", fmt::format("eye_run_corrupt_{}", ::getpid())});
  EXPECT_EQ(run.code, 0) << run.text;
  EXPECT_THAT(run.text, HasSubstr("camera overhead: frame_000015.png skipped: not an image OpenCV "
                                  "can read"));
  EXPECT_THAT(run.text, HasSubstr("stopped: 29 frames"));
  EXPECT_THAT(run.text, HasSubstr("1 unreadable"));
}

// --- docs/tutorials/mount-a-roof-tag.md, step by step ---

// The fenced blocks of a Markdown file, in order, with their info strings.
std::vector<std::pair<std::string, std::string>> FencedBlocks(const fs::path& md) {
  std::vector<std::pair<std::string, std::string>> blocks;
  std::ifstream in(md);
  std::optional<std::pair<std::string, std::string>> open;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("```", 0) == 0) {
      if (open) {
        blocks.push_back(*open);
        open.reset();
      } else {
        open = std::pair{line.substr(3), std::string()};
      }
    } else if (open) {
      open->second += line + "\n";
    }
  }
  return blocks;
}

// The tutorial's shell block run as written, in the source folder, with ~ the test's folder,
// /tmp/mount a folder of it and build/bin/ the programs' folder.
ProgramOutput RunShell(const std::string& block, const fs::path& home) {
  std::string script = block;
  script = std::regex_replace(script, std::regex("build/bin/"), ProgramPath(""));
  script = std::regex_replace(script, std::regex("/tmp/mount"), (home / "mount").string());
  return RunProgram({"env", "HOME=" + home.string(), "/bin/sh", "-ec",
                     "cd " + test::SourceDir().string() + "\n" + script});
}

TEST(MountARoofTagTutorial, ItsDeclarationLoadsAndTheTwinsFramesAreLocalisedOrRaiseTheEvent) {
  const test::TempDir home("eye_tutorial");
  const auto blocks = FencedBlocks(test::SourceDir() / "docs/tutorials/mount-a-roof-tag.md");
  const auto find = [&](const std::string& info, const std::string& containing) {
    for (const auto& [i, text] : blocks) {
      if (i == info && text.find(containing) != std::string::npos) return text;
    }
    ADD_FAILURE() << "no ```" << info << " block with \"" << containing << "\" in the tutorial";
    return std::string();
  };
  // Step 0: the copies.
  const ProgramOutput copy = RunShell(find("sh", "mkdir -p ~/lab"), home.path());
  ASSERT_EQ(copy.code, 0) << copy.text;
  const fs::path city = home.path() / "lab/cities/small_town.yaml";
  ASSERT_TRUE(fs::exists(city));
  const std::string shipped = config::ReadFile(city);

  // Step 4: nigel_1's line replaced by the tutorial's.
  const std::string snippet = find("yaml", "name: nigel_1");
  ASSERT_FALSE(snippet.empty());
  const std::string line = "    - {name: nigel_1, tag_id: 1}\n";
  ASSERT_NE(shipped.find(line), std::string::npos) << "the shipped small town changed";
  std::string declared = shipped;
  declared.replace(declared.find(line), line.size(), snippet);
  std::ofstream(city) << declared;
  // It loads, and the Eye has the mounting the snippet says (read on its own).
  const EyeConfig eye = LoadEyeConfig(city);
  const auto entry = config::LoadString<VehicleTagConfig>(snippet.substr(snippet.find('{')),
                                                          "the tutorial's snippet");
  ASSERT_EQ(eye.vehicles.at(0), entry);
  EXPECT_NE(entry.mount, camera::RoofTagMount{}) << "the tutorial's tag is mounted as shipped";

  // Step 5: the twin, localised with the declaration: the summary the tutorial shows, and no
  // tag_mounting event.
  const std::string commands = find("sh", "autodrive-sim render");
  const ProgramOutput check = RunShell(commands, home.path());
  ASSERT_EQ(check.code, 0) << check.text;
  std::cout << check.text;
  const std::string summary = find("", "localize: summary:");
  ASSERT_FALSE(summary.empty());
  EXPECT_THAT(check.text, HasSubstr(summary)) << "the tutorial's summary line";
  EXPECT_TRUE(MountingEvents(check.text).empty()) << check.text;

  // The same frames with nigel_1 as shipped: the event the tutorial quotes, with its figures
  // as measured here (they depend on the renderer's arithmetic to a few tenths).
  std::ofstream(city) << shipped;
  const ProgramOutput wrong =
      RunProgram({ProgramPath("autodrive-eye"), "localize", "--config", city.string(), "--images",
                  (home.path() / "mount").string(), "--out",
                  (home.path() / "mount/poses_shipped.csv").string()});
  ASSERT_EQ(wrong.code, 0) << wrong.text;
  const auto events = MountingEvents(wrong.text);
  ASSERT_EQ(events.count("nigel_1"), 1u) << wrong.text;
  const std::string quoted = find("", "tag_mounting nigel_1");
  std::string pattern = std::regex_replace(quoted.substr(0, quoted.size() - 1),
                                           std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)");
  pattern = std::regex_replace(pattern, std::regex(R"([0-9]+\\\.[0-9]+)"), "-?[0-9.]+");
  pattern = std::regex_replace(pattern, std::regex(R"([0-9]+ of the last)"), "[0-9]+ of the last");
  EXPECT_TRUE(std::regex_match(events.at("nigel_1").front().line, std::regex(pattern)))
      << events.at("nigel_1").front().line << "\ndoes not read as the tutorial's\n"
      << quoted;
}

}  // namespace
}  // namespace autodrive::eye
