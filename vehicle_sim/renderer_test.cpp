// The cameras' renderer: AprilTag's own detector finds the tags it draws where the camera model
// says they are; the front camera sees the lane markings where the map has them and the lit lamp
// of a light head; effects change what they should and nothing else. The frames are written to
// the build folder (AUTODRIVE_FRAMES_DIR) to be looked at.

#include "vehicle_sim/renderer.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/test_support.h"
#include "maps/builder.h"
#include "maps/layout.h"
#include "maps/map.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/sim_config.h"

namespace autodrive::vehicle_sim {
namespace {

const maps::Map& DrivingSchool() {
  static const maps::Map map = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / "driving_school.yaml").string()));
  return map;
}

// Reference tags on the ground: ids 100.. in the empty tiles' corners.
std::vector<GroundTag> GroundTags() {
  return {GroundTag{{"tag36h11", 100, 0.0762}, 0.5, 0.5, 0.0},
          GroundTag{{"tag36h11", 101, 0.0762}, 4.5, 4.5, 0.3},
          GroundTag{{"tag36h11", 102, 0.0762}, 3.5, 0.5, -0.7},
          GroundTag{{"tag36h11", 103, 0.0762}, 1.5, 3.5, 2.0}};
}

std::shared_ptr<const RenderWorld> SchoolWorld() {
  static const auto world = [] {
    RenderWorldOptions options;
    options.ground_tags = GroundTags();
    return std::make_shared<const RenderWorld>(DrivingSchool(), GeometryFromMap(DrivingSchool()),
                                               options);
  }();
  return world;
}

const VehicleParams& Nigel() {
  static const VehicleParams params;
  return params;
}

// Four cars where the simulator spawns them, tags 1..4.
std::vector<RenderVehicle> Cars() {
  SimConfig sim;
  sim.vehicles.clear();
  for (int i = 1; i <= 4; ++i)
    sim.vehicles.push_back({"nigel_" + std::to_string(i), {}, {}, {}, {}});
  const std::vector<RigidTransform2> poses = SpawnPoses(sim, DrivingSchool());
  std::vector<RenderVehicle> cars;
  const std::array<Rgb, 4> colours{Rgb{200, 30, 30}, Rgb{30, 90, 200}, Rgb{240, 200, 30},
                                   Rgb{30, 160, 60}};
  for (int i = 0; i < 4; ++i) {
    RenderVehicle car;
    car.index = i;
    const auto& pose = poses[static_cast<std::size_t>(i)];
    car.X_MV = Eigen::Translation3d(pose.translation().x(), pose.translation().y(), 0.0) *
               Eigen::AngleAxisd(pose.rotation().angle(), Eigen::Vector3d::UnitZ());
    car.params = &Nigel();
    car.look.colour = colours[static_cast<std::size_t>(i)];
    car.look.tag = TagSpec{"tag36h11", i + 1, 0.0762};
    car.headlights = i % 2 == 0;
    cars.push_back(car);
  }
  return cars;
}

// Every tag's four corners in the map frame, by id.
std::map<int, std::array<Eigen::Vector3d, 4>> TruthCorners(const std::vector<RenderVehicle>& cars) {
  std::map<int, std::array<Eigen::Vector3d, 4>> out;
  for (const auto& car : cars) {
    const Eigen::Isometry3d X_MT = VehicleTagPose(car);
    auto& c = out[car.look.tag->id];
    const auto corners = TagCorners(car.look.tag->size_m);
    for (int k = 0; k < 4; ++k)
      c[static_cast<std::size_t>(k)] = X_MT * corners[static_cast<std::size_t>(k)];
  }
  for (const auto& g : GroundTags()) {
    const Eigen::Isometry3d X_MT = Eigen::Translation3d(g.x_m, g.y_m, 0.0005) *
                                   Eigen::AngleAxisd(g.yaw_rad, Eigen::Vector3d::UnitZ());
    auto& c = out[g.tag.id];
    const auto corners = TagCorners(g.tag.size_m);
    for (int k = 0; k < 4; ++k)
      c[static_cast<std::size_t>(k)] = X_MT * corners[static_cast<std::size_t>(k)];
  }
  return out;
}

void Save(const Image& image, const std::string& name) {
  const char* dir = std::getenv("AUTODRIVE_FRAMES_DIR");
  if (dir == nullptr || *dir == '\0') return;
  std::filesystem::create_directories(dir);
  cv::Mat rgb(image.height_px, image.width_px, CV_8UC3,
              const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::imwrite((std::filesystem::path(dir) / name).string(), bgr);
}

struct Detection {
  int id = 0;
  std::array<Eigen::Vector2d, 4> corners;
  double margin = 0;
};

std::vector<Detection> Detect(const Image& image) {
  cv::Mat rgb(image.height_px, image.width_px, CV_8UC3,
              const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  detector->quad_decimate = 1.0f;
  detector->nthreads = 1;
  image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step), gray.data};
  zarray_t* detections = apriltag_detector_detect(detector, &im);
  std::vector<Detection> out;
  for (int i = 0; i < zarray_size(detections); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(detections, i, &det);
    Detection d;
    d.id = det->id;
    d.margin = det->decision_margin;
    // The AprilTag library puts a pixel's centre at +0.5 (its decimation maps x to
    // (x - 0.5) d + 0.5); OpenCV's convention, the camera model's, at +0.
    for (int k = 0; k < 4; ++k) {
      d.corners[static_cast<std::size_t>(k)] = {det->p[k][0] - 0.5, det->p[k][1] - 0.5};
    }
    out.push_back(d);
  }
  apriltag_detections_destroy(detections);
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  return out;
}

camera::Camera Overhead(double tilt_rad, std::vector<double> distortion = {}) {
  // fx = fy = 1000 px, principal point at the image's middle (the existing helper: a
  // "focal length" of 1000 over a "sensor" 1920 wide).
  camera::Intrinsics k = camera::IntrinsicsFromSensor(1000.0, 1920.0, 1920, 1080);
  k.distortion = std::move(distortion);
  camera::Camera cam{"overhead", "overhead_optical", "map", camera::CameraModel(k), {}};
  // Above the middle of the map, or tilted 20° forward (north) from south of it, image top to
  // the north.
  const Eigen::Vector3d p = tilt_rad == 0.0
                                ? Eigen::Vector3d(2.5, 2.5, 4.8)
                                : Eigen::Vector3d(2.5, 2.5 - 4.6 * std::tan(tilt_rad), 4.6);
  cam.X_PC = camera::CameraPoseFromMount(p, {0.0, kPi / 2 - tilt_rad, kPi / 2});
  return cam;
}

// Fully visible: all four corners (and a cell's margin around them) inside the image.
bool FullyVisible(const camera::Camera& cam, const std::array<Eigen::Vector3d, 4>& corners) {
  for (const auto& c : corners) {
    const auto px = cam.ProjectFromParent(c);
    if (!px || px->x() < 5 || px->y() < 5 || px->x() > cam.model.intrinsics().width_px - 6 ||
        px->y() > cam.model.intrinsics().height_px - 6) {
      return false;
    }
  }
  return true;
}

struct GeometryResult {
  int expected = 0;
  int found = 0;
  double rms_px = 0;
  double max_px = 0;
};

GeometryResult CheckTags(const camera::Camera& cam, const FilmOptions& film,
                         const std::string& name, const std::vector<RenderVehicle>& cars = Cars()) {
  CameraRenderer renderer(SchoolWorld(), cam.model.intrinsics(), film);
  Image image;
  FrameState frame;
  frame.vehicles = cars;
  renderer.Render(cam.X_PC, frame, image, std::nullopt, Eigen::Vector3d::Zero(),
                  Eigen::Vector3d::Zero(), 7);
  Save(image, name);
  const auto truth = TruthCorners(cars);
  const auto detections = Detect(image);
  GeometryResult r;
  double sum2 = 0;
  int n = 0;
  for (const auto& [id, corners] : truth) {
    if (!FullyVisible(cam, corners)) continue;
    ++r.expected;
    const auto it = std::find_if(detections.begin(), detections.end(),
                                 [id = id](const Detection& d) { return d.id == id; });
    if (it == detections.end()) {
      ADD_FAILURE() << name << ": tag " << id << " not detected";
      continue;
    }
    ++r.found;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d p = *cam.ProjectFromParent(corners[static_cast<std::size_t>(k)]);
      const double e = (it->corners[static_cast<std::size_t>(k)] - p).norm();
      sum2 += e * e;
      r.max_px = std::max(r.max_px, e);
      ++n;
    }
  }
  for (const auto& d : detections) {
    EXPECT_TRUE(truth.contains(d.id)) << name << ": a tag " << d.id << " that is not in the world";
  }
  r.rms_px = n > 0 ? std::sqrt(sum2 / n) : 0;
  return r;
}

TEST(Renderer, OverheadStraightDownTagsAreDetectedWithinHalfAPixel) {
  const GeometryResult r = CheckTags(Overhead(0.0), {}, "overhead_straight.png");
  EXPECT_EQ(r.expected, 8);
  EXPECT_EQ(r.found, r.expected);
  EXPECT_LT(r.rms_px, 0.5) << "max " << r.max_px;
  std::cout << "straight: " << r.found << "/" << r.expected << " tags, corner RMS " << r.rms_px
            << " px, max " << r.max_px << " px\n";
}

TEST(Renderer, OverheadTilted20DegreesTagsAreDetectedWithinHalfAPixel) {
  const GeometryResult r = CheckTags(Overhead(20.0 * kPi / 180), {}, "overhead_tilted.png");
  EXPECT_EQ(r.expected, 8);
  EXPECT_EQ(r.found, r.expected);
  EXPECT_LT(r.rms_px, 0.5) << "max " << r.max_px;
  std::cout << "tilted: " << r.found << "/" << r.expected << " tags, corner RMS " << r.rms_px
            << " px, max " << r.max_px << " px\n";
}

// Roof tags turned and moved on the roof (docs/eye.md, "The roof tag's mounting"): AprilTag
// reports each tag's corners in the order of the tag's own frame, so a tag drawn turned the
// wrong way round would put every corner a quarter turn or more from where VehicleTagPose
// says.
TEST(Renderer, RoofTagsAreDrawnTurnedAndPlacedAsTheirMountingSays) {
  auto cars = Cars();
  const std::array<camera::RoofTagMount, 4> mounts{
      camera::RoofTagMount{90.0, 0.07077, 0.0}, camera::RoofTagMount{180.0, 0.05, 0.02},
      camera::RoofTagMount{270.0, 0.09, -0.015}, camera::RoofTagMount{30.0, 0.07077, 0.0}};
  for (std::size_t i = 0; i < cars.size(); ++i) cars[i].look.tag_mount = mounts[i];
  // The mounting as the car's yaw would have it: the tag's yaw is the car's + tag_yaw_deg - 90°.
  for (std::size_t i = 0; i < cars.size(); ++i) {
    const Eigen::Isometry3d X_MT = VehicleTagPose(cars[i]);
    const double car_yaw = std::atan2(cars[i].X_MV.linear()(1, 0), cars[i].X_MV.linear()(0, 0));
    const double tag_yaw = std::atan2(X_MT.linear()(1, 0), X_MT.linear()(0, 0));
    EXPECT_NEAR(WrapAngle(tag_yaw - mounts[i].TagYaw(car_yaw)), 0.0, 1e-9) << i;
    const Eigen::Vector3d p_VT = cars[i].X_MV.inverse() * X_MT.translation();
    EXPECT_TRUE(p_VT.isApprox(Eigen::Vector3d(mounts[i].ahead_m, mounts[i].left_m, 0.257), 1e-9))
        << p_VT.transpose();
  }
  const GeometryResult r = CheckTags(Overhead(0.0), {}, "overhead_turned_tags.png", cars);
  EXPECT_EQ(r.expected, 8);
  EXPECT_EQ(r.found, r.expected);
  EXPECT_LT(r.rms_px, 0.5) << "max " << r.max_px;
}

TEST(Renderer, WithNoiseBlurExposureAndMotionBlurEveryVisibleTagIsStillDetected) {
  FilmOptions film;
  // A sharp lens's blur and a lit lab's sensor noise; at 4.6 mm a pixel the far tags' bits are
  // under 2 px wide, so much more blur erases them (as it would a real camera's).
  film.noise_sigma = 3.0;
  film.blur_sigma_px = 0.5;
  film.exposure = 1.1;
  film.exposure_time_s = 0.01;  // cars at 0.26 m/s move 2.6 mm (half a pixel) in it
  const camera::Camera cam = Overhead(20.0 * kPi / 180);
  auto cars = Cars();
  for (auto& car : cars) car.v_M_mps = car.X_MV.linear() * Eigen::Vector3d(0.26, 0, 0);
  CameraRenderer renderer(SchoolWorld(), cam.model.intrinsics(), film);
  Image image;
  FrameState frame;
  frame.vehicles = cars;
  renderer.Render(cam.X_PC, frame, image, std::nullopt, Eigen::Vector3d::Zero(),
                  Eigen::Vector3d::Zero(), 11);
  Save(image, "overhead_tilted_effects.png");
  const auto truth = TruthCorners(cars);
  const auto detections = Detect(image);
  int visible = 0;
  for (const auto& [id, corners] : truth) {
    if (!FullyVisible(cam, corners)) continue;
    ++visible;
    EXPECT_TRUE(std::any_of(detections.begin(), detections.end(),
                            [id = id](const Detection& d) { return d.id == id; }))
        << "tag " << id << " (" << detections.size() << " detections)";
  }
  EXPECT_EQ(visible, 8);
  // The effects are there: the image differs from the clean one by noise of about the
  // configured size.
  CameraRenderer clean(SchoolWorld(), cam.model.intrinsics(), {});
  Image plain;
  clean.Render(cam.X_PC, frame, plain);
  double sum = 0;
  for (std::size_t k = 0; k < plain.rgb.size(); ++k) {
    sum += std::abs(static_cast<int>(image.rgb[k]) - static_cast<int>(plain.rgb[k]));
  }
  EXPECT_GT(sum / static_cast<double>(plain.rgb.size()), 2.0);
}

// Nigel's front camera, from NIGEL.md: at (0.195, 0, 0.110) in the car, pitched 7.3° down.
Eigen::Isometry3d FrontCamera(const Eigen::Isometry3d& X_MV) {
  return X_MV * camera::CameraPoseFromMount({0.195, 0, 0.110}, {0, 7.3 * kPi / 180, 0});
}
Eigen::Isometry3d RearCamera(const Eigen::Isometry3d& X_MV) {
  return X_MV * camera::CameraPoseFromMount({-0.035, 0, 0.110}, {0, 7.3 * kPi / 180, kPi});
}

// A car on the first lane into the intersection, `before_m` before its stop line, facing along
// it; and the head that faces it.
struct Approaching {
  RenderVehicle car;
  const maps::Lane* lane = nullptr;
  const maps::SignalHead* head = nullptr;
};
Approaching CarBeforeTheStopLine(double before_m) {
  const maps::Map& map = DrivingSchool();
  Approaching a;
  for (const auto& lane : map.lanes) {
    if (lane.stop_line && lane.ingress_of) {
      a.lane = &lane;
      break;
    }
  }
  EXPECT_NE(a.lane, nullptr);
  for (const auto& head : map.signal_heads) {
    if (head.intersection == *a.lane->ingress_of && head.approach == *a.lane->ingress_approach)
      a.head = &head;
  }
  EXPECT_NE(a.head, nullptr);
  // Walk back along the centreline.
  const auto& c = a.lane->centreline;
  double left = before_m;
  std::size_t k = c.size() - 1;
  while (k > 0 && left > (c[k] - c[k - 1]).norm()) {
    left -= (c[k] - c[k - 1]).norm();
    --k;
  }
  const Eigen::Vector2d dir = (c[k] - c[k - 1]).normalized();
  const Eigen::Vector2d p = c[k] - dir * left;
  a.car.index = 0;
  a.car.params = &Nigel();
  // The rear axle `before_m` before the line puts the front camera 0.195 m nearer.
  a.car.X_MV = Eigen::Translation3d(p.x(), p.y(), 0.0) *
               Eigen::AngleAxisd(std::atan2(dir.y(), dir.x()), Eigen::Vector3d::UnitZ());
  a.car.look.tag = TagSpec{"tag36h11", 1, 0.0762};
  return a;
}

// Pixels within `radius` px of `centre` for which `pred` holds.
template <typename Pred>
int CountNear(const Image& image, const Eigen::Vector2d& centre, int radius, Pred pred) {
  int n = 0;
  for (int v = static_cast<int>(centre.y()) - radius; v <= static_cast<int>(centre.y()) + radius;
       ++v) {
    for (int u = static_cast<int>(centre.x()) - radius; u <= static_cast<int>(centre.x()) + radius;
         ++u) {
      if (u < 0 || v < 0 || u >= image.width_px || v >= image.height_px) continue;
      const std::uint8_t* p =
          &image.rgb[(static_cast<std::size_t>(v) * static_cast<std::size_t>(image.width_px) +
                      static_cast<std::size_t>(u)) *
                     3];
      if (pred(p[0], p[1], p[2])) ++n;
    }
  }
  return n;
}

TEST(Renderer, TheFrontCameraSeesTheLaneMarkingsWhereTheMapHasThemAndTheLitLamp) {
  const Approaching a = CarBeforeTheStopLine(1.0);
  ASSERT_NE(a.lane, nullptr);
  ASSERT_NE(a.head, nullptr);
  const maps::Map& map = DrivingSchool();
  const camera::CameraModel model(camera::PiCameraV21Intrinsics());
  CameraRenderer renderer(SchoolWorld(), model.intrinsics(), {});
  const std::vector<RenderVehicle> cars{a.car};
  const Eigen::Isometry3d X_MC = FrontCamera(a.car.X_MV);
  const Eigen::Isometry3d X_CM = X_MC.inverse();
  const auto pixel = [&](const Eigen::Vector3d& p_M) { return model.Project(X_CM * p_M); };

  for (const bool red : {true, false}) {
    const std::vector<HeadLamps> lamps{HeadLamps{a.head->id, red, false, !red}};
    FrameState frame;
    frame.vehicles = cars;
    frame.lamps = lamps;
    Image image;
    renderer.Render(X_MC, frame, image, /*exclude=*/0);
    Save(image, red ? "front_red.png" : "front_green.png");

    // The kerb line (solid white along the lane's right boundary) and the road between it and
    // the centre line, at 0.4 to 0.8 m ahead of the camera.
    int kerb_points = 0;
    for (std::size_t k = 0; k < a.lane->right_boundary.size(); ++k) {
      const Eigen::Vector2d q = a.lane->right_boundary[k];
      const Eigen::Vector3d in_car = a.car.X_MV.inverse() * Eigen::Vector3d(q.x(), q.y(), 0);
      if (in_car.x() < 0.5 || in_car.x() > 0.9) continue;  // the stop line is at 1.0 m
      const auto px = pixel({q.x(), q.y(), 0});
      ASSERT_TRUE(px && model.IsInImage(*px));
      const int white = CountNear(
          image, *px, 1, [](int r, int g, int b) { return r > 200 && g > 200 && b > 200; });
      EXPECT_GE(white, 5) << "no kerb line at " << px->transpose() << " (map " << q.transpose()
                          << ")";
      const Eigen::Vector2d mid = (a.lane->right_boundary[k] + a.lane->left_boundary[k]) / 2;
      const auto pm = pixel({mid.x(), mid.y(), 0});
      ASSERT_TRUE(pm);
      EXPECT_EQ(CountNear(image, *pm, 2,
                          [](int r, int g, int b) { return r > 100 || g > 100 || b > 100; }),
                0)
          << "the middle of the lane is not road at " << pm->transpose();
      ++kerb_points;
    }
    EXPECT_GE(kerb_points, 5);
    // The stop line: white across the lane's end.
    const Eigen::Vector2d stop = (a.lane->stop_line->left + a.lane->stop_line->right) / 2;
    const auto ps = pixel({stop.x(), stop.y(), 0});
    ASSERT_TRUE(ps && model.IsInImage(*ps));
    EXPECT_GE(
        CountNear(image, *ps, 1, [](int r, int g, int b) { return r > 200 && g > 200 && b > 200; }),
        5);

    // The head: its red lamp lit and its green dark, or the other way round.
    const double ground = 0.0;
    const Eigen::Vector2d h = a.head->X_MH.translation();
    const Eigen::Vector2d toward = a.head->X_MH.rotation() * Eigen::Vector2d::UnitX();
    const Eigen::Vector2d face = h + toward * 0.03;
    const auto pr = pixel({face.x(), face.y(), ground + a.head->lamp_heights_m[0]});
    const auto pg = pixel({face.x(), face.y(), ground + a.head->lamp_heights_m[2]});
    ASSERT_TRUE(pr && model.IsInImage(*pr)) << "the head is out of the picture";
    ASSERT_TRUE(pg && model.IsInImage(*pg));
    const auto lit_red = [](int r, int g, int b) { return r > 220 && g < 80 && b < 80; };
    const auto lit_green = [](int r, int g, int b) { return g > 220 && r < 80 && b < 150; };
    EXPECT_EQ(CountNear(image, *pr, 6, lit_red) >= 10, red) << pr->transpose();
    EXPECT_EQ(CountNear(image, *pg, 6, lit_green) >= 10, !red) << pg->transpose();
    (void)map;
  }

  // The rear camera, for the eye.
  Image rear;
  FrameState frame;
  frame.vehicles = cars;
  renderer.Render(RearCamera(a.car.X_MV), frame, rear, 0);
  Save(rear, "rear.png");
}

TEST(Renderer, TheAvx2AndPortableGroundSamplersDrawTheSamePicture) {
  // Where the CPU has AVX2 the ground is sampled by our own gathering code, elsewhere by
  // cv::remap: the two must agree (weights in 1/256 against OpenCV's 1/32).
  if (!RenderAvx2Available()) {
    GTEST_SKIP() << "no AVX2 ground sampler here (built with AUTODRIVE_RENDER_AVX2=OFF, not "
                    "x86-64, or the CPU lacks AVX2 or FMA): only the portable one runs";
  }
  ASSERT_TRUE(SchoolWorld()->uses_avx2());
  RenderWorldOptions portable_options;
  portable_options.ground_tags = GroundTags();
  portable_options.allow_avx2 = false;
  const auto portable = std::make_shared<const RenderWorld>(
      DrivingSchool(), GeometryFromMap(DrivingSchool()), portable_options);
  ASSERT_FALSE(portable->uses_avx2());
  const Approaching a = CarBeforeTheStopLine(1.0);
  const camera::Intrinsics k = camera::PiCameraV21Intrinsics();
  const auto cars = Cars();
  FrameState frame;
  frame.vehicles = cars;
  for (const Eigen::Isometry3d& X_MC : {FrontCamera(a.car.X_MV), Overhead(20.0 * kPi / 180).X_PC}) {
    Image fast, slow;
    CameraRenderer(SchoolWorld(), k, {}).Render(X_MC, frame, fast);
    CameraRenderer(portable, k, {}).Render(X_MC, frame, slow);
    ASSERT_EQ(fast.rgb.size(), slow.rgb.size());
    double sum = 0;
    int large = 0;
    for (std::size_t i = 0; i < fast.rgb.size(); ++i) {
      const int d = std::abs(static_cast<int>(fast.rgb[i]) - static_cast<int>(slow.rgb[i]));
      sum += d;
      large += d > 24 ? 1 : 0;
    }
    EXPECT_LT(sum / static_cast<double>(fast.rgb.size()), 0.5);
    EXPECT_LT(large, static_cast<int>(fast.rgb.size() / 2000)) << "bytes differing by > 24";
  }
}

TEST(Renderer, RaisedAndSlopingGroundIsDrawnAtItsHeight) {
  // The small town's northern row is a terrace 5 cm up, reached by ramps. Seen from a camera low
  // in the south-west looking north-east, the kerb lines on the terrace and on a ramp must be
  // where their 3-D points project, not where the same map point at z = 0 would.
  static const maps::Map town = maps::Build(
      maps::LoadLayout((test::SourceDir() / "config" / "maps" / "small_town.yaml").string()));
  const StaticGeometry geometry = GeometryFromMap(town);
  const auto world = std::make_shared<const RenderWorld>(town, geometry);
  const camera::CameraModel model(camera::IntrinsicsFromSensor(3.04, 3.68, 1280, 720));
  CameraRenderer renderer(world, model.intrinsics(), {});
  const double size_y = town.size_m().y();
  const Eigen::Isometry3d X_MC =
      camera::CameraPoseFromMount({town.size_m().x() / 2, size_y - 3.2, 0.6}, {0, 0.35, kPi / 2});
  Image image;
  renderer.Render(X_MC, {}, image);
  Save(image, "small_town_terrace.png");
  const Eigen::Isometry3d X_CM = X_MC.inverse();
  int checked = 0, off = 0;
  for (const auto& lane : town.lanes) {
    for (std::size_t k = 0; k < lane.right_boundary.size(); k += 10) {
      const Eigen::Vector2d q = lane.right_boundary[k];
      const double z = geometry.terrain.HeightAt(q.x(), q.y());
      if (z < 0.01) continue;  // raised or sloping ground only
      const auto px = model.Project(X_CM * Eigen::Vector3d(q.x(), q.y(), z));
      if (!px || !model.IsInImage(*px) || px->y() < 40 || px->y() > 680) continue;
      const auto white = [](int r, int g, int b) { return r > 200 && g > 200 && b > 200; };
      if (CountNear(image, *px, 1, white) >= 3) {
        ++checked;
      } else {
        ++off;
      }
    }
  }
  EXPECT_GE(checked, 10);
  EXPECT_LE(off, checked / 10) << checked << " kerb points found white, " << off << " not";
}

}  // namespace
}  // namespace autodrive::vehicle_sim
