#include "vehicle_sim/render/camera_rays.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "common/test_support.h"
#include "vehicle_sim/render/raster.h"
#include "vehicle_sim/render/scene.h"

namespace autodrive::vehicle_sim::internal {
namespace {

camera::Intrinsics Distorted() {
  camera::Intrinsics k = camera::PiCameraV21Intrinsics();
  k.distortion = {-0.28, 0.07, 0.001, -0.0005, 0};
  return k;
}

TEST(RenderCameraRays, EachPixelsRayIsTheLensModelsUndistortedPoint) {
  for (const bool distorted : {false, true}) {
    const camera::Intrinsics k = distorted ? Distorted() : camera::PiCameraV21Intrinsics();
    const CameraRays rays(k);
    EXPECT_EQ(rays.distorted, distorted);
    for (int v = 0; v < k.height_px; v += 37) {
      for (int u = 0; u < k.width_px; u += 41) {
        const auto xy = rays.model.UndistortToNormalized({u, v});
        ASSERT_TRUE(xy.has_value());
        const Eigen::Vector3f r = rays.Ray(u, v);
        EXPECT_NEAR(r.x(), xy->x(), 1e-5) << u << " " << v;
        EXPECT_NEAR(r.y(), xy->y(), 1e-5) << u << " " << v;
        EXPECT_EQ(r.z(), 1.0f);
      }
    }
  }
}

// Against brute force: every point of a random box's surface that the camera sees falls in the
// box's pixel rectangle, and a box whose rectangle is empty has no point in view.
TEST(RenderCameraRays, APartsRectangleHoldsEveryPixelItsSurfaceIsSeenAt) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> pos(-3.0, 3.0), size(0.01, 0.6), angle(-kPi, kPi);
  const int cases = 300 * test::SoakFactor();
  for (const camera::Intrinsics& k : {camera::PiCameraV21Intrinsics(), Distorted()}) {
    const CameraRays rays(k);
    const Eigen::Isometry3d X_MC = camera::CameraPoseFromMount({0, 0, 0.3}, {0, 0.2, 0});
    const Eigen::Isometry3d X_CM = X_MC.inverse();
    int seen = 0;
    for (int c = 0; c < cases; ++c) {
      RenderPart part;
      part.R_MB = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      part.p_MB = {pos(rng), pos(rng), 0.3 + pos(rng) / 10};
      part.half = {size(rng), size(rng), size(rng)};
      const PixelRect rect = rays.Bound(part, X_MC);
      for (int s = 0; s < 200; ++s) {
        // A point on a random face.
        Eigen::Vector3d local(std::uniform_real_distribution<double>(-1, 1)(rng),
                              std::uniform_real_distribution<double>(-1, 1)(rng),
                              std::uniform_real_distribution<double>(-1, 1)(rng));
        const int axis = s % 3;
        local[axis] = s % 2 == 0 ? 1 : -1;
        const Eigen::Vector3d p_C = X_CM * (part.R_MB * local.cwiseProduct(part.half) + part.p_MB);
        if (p_C.z() <= 1e-3) continue;
        const auto px = rays.model.Project(p_C);
        if (!px || !rays.model.IsInImage(*px)) continue;
        ++seen;
        const int u = static_cast<int>(std::lround(px->x()));
        const int v = static_cast<int>(std::lround(px->y()));
        ASSERT_FALSE(rect.empty()) << "case " << c << ": a point seen at " << u << " " << v;
        EXPECT_TRUE(u >= rect.x0 && u < rect.x1 && v >= rect.y0 && v < rect.y1)
            << "case " << c << ": " << u << " " << v << " outside [" << rect.x0 << ", " << rect.x1
            << ") x [" << rect.y0 << ", " << rect.y1 << ")";
        // Its bounding sphere is in view too.
        ASSERT_TRUE(rays.SphereInView(X_CM * part.p_MB, part.half.norm())) << "case " << c;
      }
    }
    EXPECT_GT(seen, cases * 10);  // the test sees something
  }
}

TEST(RenderCameraRays, APartBehindTheCameraHasNoPixels) {
  const CameraRays rays(camera::PiCameraV21Intrinsics());
  RenderPart part;
  part.p_MB = {0, 0, -1};  // the camera at the origin looks along +z
  part.half = {0.1, 0.1, 0.1};
  EXPECT_TRUE(rays.Bound(part, Eigen::Isometry3d::Identity()).empty());
  EXPECT_FALSE(rays.SphereInView({0, 0, -1}, 0.1));
  part.p_MB = {0, 0, 1};
  EXPECT_FALSE(rays.Bound(part, Eigen::Isometry3d::Identity()).empty());
}

TEST(RenderLight, TheGroundIsShownAsItIsAndFacesAwayFromTheLightGetTheAmbientShare) {
  FilmOptions film;
  film.light_elevation_rad = 0.5;
  const Light light(film);
  EXPECT_FLOAT_EQ(light.Shade({0, 0, 1}), 1.0f);
  const double ground = film.ambient + film.light_intensity * std::sin(0.5);
  EXPECT_FLOAT_EQ(light.Shade({0, 0, -1}), static_cast<float>(film.ambient / ground));
  // The face that looks at the light is the brightest.
  EXPECT_GT(light.Shade(light.direction), light.Shade({0, 0, 1}));
}

}  // namespace
}  // namespace autodrive::vehicle_sim::internal
