#include "vehicle_sim/render/film.h"

#include <gtest/gtest.h>

#include <chrono>
#include <vector>

namespace autodrive::vehicle_sim::internal {
namespace {

using Seconds = std::chrono::duration<double>;

TEST(RenderFilm, SubFramesAreSpreadEvenlyOverTheExposureCentredOnTheFrame) {
  const Seconds exposure(0.010);
  const int n = 4;
  const double expected[] = {-0.00375, -0.00125, 0.00125, 0.00375};
  for (int s = 0; s < n; ++s) {
    EXPECT_NEAR(MotionBlur::Offset(exposure, s, n).count(), expected[s], 1e-15) << s;
  }
  EXPECT_EQ(MotionBlur::Offset(exposure, 0, 1).count(), 0.0);
}

TEST(RenderFilm, ASubFrameMovesVehiclesTrafficAndTheClockByTheirVelocities) {
  RenderVehicle car;
  car.X_MV.translation() = Eigen::Vector3d(1, 2, 0);
  car.v_M_mps = Eigen::Vector3d(0.5, 0, 0);
  car.w_M_radps = Eigen::Vector3d(0, 0, 1.0);
  RenderTraffic object;
  object.X_MO =
      Eigen::Translation3d(5, 5, 0) * Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ());
  object.speed_mps = 2.0;
  const std::vector<RenderVehicle> cars{car};
  const std::vector<RenderTraffic> traffic{object};
  FrameState frame;
  frame.time_s = 3.0;
  frame.vehicles = cars;
  frame.traffic = traffic;
  MotionBlur blur;
  blur.Begin(frame, 3);
  const FrameState sub = blur.SubFrame(frame, Seconds(0.1));
  EXPECT_DOUBLE_EQ(sub.time_s, 3.1);
  ASSERT_EQ(sub.vehicles.size(), 1u);
  EXPECT_TRUE(sub.vehicles[0].X_MV.translation().isApprox(Eigen::Vector3d(1.05, 2, 0)));
  const Eigen::Matrix3d R = sub.vehicles[0].X_MV.linear();
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), 0.1, 1e-12);
  ASSERT_EQ(sub.traffic.size(), 1u);
  // Along the object's own x, which points north.
  EXPECT_TRUE(sub.traffic[0].X_MO.translation().isApprox(Eigen::Vector3d(5, 5.2, 0)));
  // The frame itself is untouched.
  EXPECT_EQ(frame.vehicles[0].X_MV.translation(), Eigen::Vector3d(1, 2, 0));
}

TEST(RenderFilm, TheAverageOfTheSubFramesIsRoundedToNearest) {
  MotionBlur blur;
  blur.Begin(FrameState{}, 3);
  blur.Add({1, 255, 0});
  blur.Add({2, 255, 1});
  std::vector<std::uint8_t> out(3);
  blur.Average(2, out);
  EXPECT_EQ(out, (std::vector<std::uint8_t>{2, 255, 1}));
}

Image Grey(int w, int h, std::uint8_t level) {
  return {w, h, std::vector<std::uint8_t>(static_cast<std::size_t>(w * h * 3), level)};
}

TEST(RenderFilm, WithoutEffectsAPictureIsLeftAsItIsAndExposureIsAGain) {
  Image image = Grey(8, 4, 100);
  Film(FilmOptions{}, 8, 4).Develop(image, 1);
  EXPECT_EQ(image.rgb, Grey(8, 4, 100).rgb);
  FilmOptions bright;
  bright.exposure = 2.0;
  Film(bright, 8, 4).Develop(image, 1);
  EXPECT_EQ(image.rgb, Grey(8, 4, 200).rgb);
  Film(bright, 8, 4).Develop(image, 1);
  EXPECT_EQ(image.rgb, Grey(8, 4, 255).rgb);  // saturates
}

TEST(RenderFilm, NoiseIsTheSameForTheSameSeedAndOfItsSigma) {
  FilmOptions noisy;
  noisy.noise_sigma = 4.0;
  const Film film(noisy, 64, 48);
  Image a = Grey(64, 48, 128), b = Grey(64, 48, 128), c = Grey(64, 48, 128);
  film.Develop(a, 7);
  film.Develop(b, 7);
  film.Develop(c, 8);
  EXPECT_EQ(a.rgb, b.rgb);
  EXPECT_NE(a.rgb, c.rgb);
  double sum = 0, sum2 = 0;
  for (const std::uint8_t v : a.rgb) {
    sum += v - 128.0;
    sum2 += (v - 128.0) * (v - 128.0);
  }
  const double n = static_cast<double>(a.rgb.size());
  EXPECT_NEAR(sum / n, 0.0, 0.2);
  EXPECT_NEAR(std::sqrt(sum2 / n), 4.0, 0.4);
}

}  // namespace
}  // namespace autodrive::vehicle_sim::internal
