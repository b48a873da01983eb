#include "vehicle_sim/render/film.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

namespace autodrive::vehicle_sim::internal {

// ---- MotionBlur -----------------------------------------------------------------------------

std::chrono::duration<double> MotionBlur::Offset(std::chrono::duration<double> exposure, int s,
                                                 int n) {
  return std::chrono::duration<double>(exposure.count() * ((s + 0.5) / n - 0.5));
}

Eigen::Isometry3d MotionBlur::Shift(const Eigen::Isometry3d& X, const Eigen::Vector3d& v,
                                    const Eigen::Vector3d& w, std::chrono::duration<double> dt) {
  Eigen::Isometry3d Y = X;
  Y.translation() += v * dt.count();
  if (w.norm() > 0) {
    Y.linear() = Eigen::AngleAxisd(w.norm() * dt.count(), w.normalized()) * X.linear();
  }
  return Y;
}

void MotionBlur::Begin(const FrameState& frame, std::size_t bytes) {
  accumulator_.assign(bytes, 0);
  moved_.assign(frame.vehicles.begin(), frame.vehicles.end());
  moved_traffic_.assign(frame.traffic.begin(), frame.traffic.end());
}

FrameState MotionBlur::SubFrame(const FrameState& frame, std::chrono::duration<double> dt) {
  for (std::size_t k = 0; k < moved_.size(); ++k) {
    moved_[k].X_MV =
        Shift(frame.vehicles[k].X_MV, frame.vehicles[k].v_M_mps, frame.vehicles[k].w_M_radps, dt);
  }
  for (std::size_t k = 0; k < moved_traffic_.size(); ++k) {
    const RenderTraffic& o = frame.traffic[k];
    moved_traffic_[k].X_MO = o.X_MO;
    moved_traffic_[k].X_MO.translation() += o.X_MO.linear().col(0) * (o.speed_mps * dt.count());
  }
  FrameState sub = frame;
  sub.vehicles = moved_;
  sub.traffic = moved_traffic_;
  sub.time_s = frame.time_s + dt.count();
  return sub;
}

void MotionBlur::Add(const std::vector<std::uint8_t>& picture) {
  for (std::size_t k = 0; k < accumulator_.size(); ++k) accumulator_[k] += picture[k];
}

void MotionBlur::Average(int n, std::vector<std::uint8_t>& out) const {
  const auto half = static_cast<std::uint16_t>(n / 2);
  const auto count = static_cast<std::uint16_t>(n);
  for (std::size_t k = 0; k < accumulator_.size(); ++k) {
    out[k] = static_cast<std::uint8_t>((accumulator_[k] + half) / count);
  }
}

// ---- Film -----------------------------------------------------------------------------------

Film::Film(const FilmOptions& options, int width_px, int height_px)
    : options_(options), w_(width_px), h_(height_px) {
  if (options_.noise_sigma > 0) {
    // Clipped at +-127 levels: beyond 3.9 sigma for the largest sigma allowed (32).
    cv::Mat normal(h_ + 64, (w_ + 64) * 3, CV_32F);
    cv::RNG rng(0x5eed);
    rng.fill(normal, cv::RNG::NORMAL, 0.0, options_.noise_sigma);
    normal.convertTo(noise_, CV_8S);
  }
}

void Film::Develop(Image& out, std::uint64_t noise_seed) const {
  cv::Mat image(h_, w_, CV_8UC3, out.rgb.data());
  if (options_.blur_sigma_px > 0) {
    // A kernel of +-2 sigma (95% of the Gaussian's weight): OpenCV's default of +-3 sigma costs
    // a third more for weights under 1%.
    const int radius = std::max(1, static_cast<int>(std::ceil(2.0 * options_.blur_sigma_px)));
    cv::GaussianBlur(image, image, cv::Size(2 * radius + 1, 2 * radius + 1),
                     options_.blur_sigma_px);
  }
  if (options_.exposure != 1.0) image.convertTo(image, CV_8UC3, options_.exposure);
  if (options_.noise_sigma > 0) {
    // A window of the camera's block of noise at an offset drawn from the frame's seed.
    std::mt19937_64 rng(noise_seed);
    const auto ox = static_cast<std::size_t>(rng() % 64), oy = static_cast<std::size_t>(rng() % 64);
    const std::size_t row = static_cast<std::size_t>(w_) * 3;
    for (std::size_t v = 0; v < static_cast<std::size_t>(h_); ++v) {
      const std::int8_t* noise = noise_.ptr<std::int8_t>(static_cast<int>(v + oy)) + ox * 3;
      std::uint8_t* px = out.rgb.data() + v * row;
      for (std::size_t k = 0; k < row; ++k) {
        const int value = px[k] + noise[k];
        px[k] = static_cast<std::uint8_t>(value < 0 ? 0 : value > 255 ? 255 : value);
      }
    }
  }
}

}  // namespace autodrive::vehicle_sim::internal
