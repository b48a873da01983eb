#include "vehicle_sim/renderer.h"

#include <chrono>
#include <cmath>

#include "common/error.h"
#include "vehicle_sim/render/film.h"
#include "vehicle_sim/render/raster.h"
#include "vehicle_sim/render/scene.h"

// The renderer in three parts (vehicle_sim/render/): the scene (what is in the world: the static
// scene once, the moving parts each frame), the raster (the camera's rays against the scene:
// ground, terrain, parts) and the film (motion blur's sub-frames, blur, exposure, noise). This
// file only puts them together.

namespace autodrive::vehicle_sim {

// ---- RenderWorld ----------------------------------------------------------------------------

struct RenderWorld::Impl {
  Impl(const maps::Map& map, const StaticGeometry& geometry, const RenderWorldOptions& options)
      : scene(map, geometry, options) {}
  internal::StaticScene scene;
};

RenderWorld::RenderWorld(const maps::Map& map, const StaticGeometry& geometry,
                         const RenderWorldOptions& options)
    : impl_(std::make_unique<Impl>(map, geometry, options)) {}

RenderWorld::~RenderWorld() = default;

const RenderWorldOptions& RenderWorld::options() const { return impl_->scene.options(); }

const internal::TagBitmap& RenderWorld::Tag(const TagSpec& tag) const {
  return impl_->scene.Tag(tag);
}

bool RenderWorld::uses_avx2() const { return impl_->scene.ground().avx2; }

bool RenderAvx2Available() { return internal::Avx2SamplerAvailable(); }

std::array<Eigen::Vector3d, 4> TagCorners(double size_m) {
  const double h = size_m / 2;
  return {Eigen::Vector3d(-h, -h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, h, 0),
          Eigen::Vector3d(-h, h, 0)};
}

Eigen::Isometry3d VehicleTagPose(const RenderVehicle& vehicle) {
  // The mounting's planar pose of the tag in the car, at the tag's height.
  const RigidTransform2 X_VT2 = vehicle.look.tag_mount.X_VT();
  Eigen::Isometry3d X_VT = Eigen::Isometry3d::Identity();
  X_VT.translation() =
      Eigen::Vector3d(X_VT2.translation().x(), X_VT2.translation().y(), vehicle.look.tag_height_m);
  X_VT.linear() = Eigen::AngleAxisd(X_VT2.yaw(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return vehicle.X_MV * X_VT;
}

// ---- CameraRenderer -------------------------------------------------------------------------

struct CameraRenderer::Impl {
  Impl(std::shared_ptr<const RenderWorld> w, const camera::Intrinsics& intrinsics,
       const FilmOptions& f)
      : world(CheckWorld(std::move(w))),
        raster(world->impl_->scene, intrinsics, f),
        film(f, intrinsics.width_px, intrinsics.height_px),
        frame_scene(world->impl_->scene.head_ids()),
        colour(raster.rays().W() * static_cast<std::size_t>(raster.rays().h) * 3) {}

  static std::shared_ptr<const RenderWorld> CheckWorld(std::shared_ptr<const RenderWorld> w) {
    AUTODRIVE_THROW_UNLESS(w != nullptr, "CameraRenderer: no world");
    return w;
  }
  void BuildFrameScene(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                       std::optional<int> exclude);
  void RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                  std::optional<int> exclude, std::uint8_t* target);

  std::shared_ptr<const RenderWorld> world;
  internal::Raster raster;
  internal::Film film;
  internal::FrameScene frame_scene;
  internal::MotionBlur motion_blur;
  std::vector<std::uint8_t> colour;  ///< a sub-frame's picture (motion blur)
  RenderStats stats;
};

// The frame's moving parts: the vehicles but the one carrying the camera; the background
// traffic, each object's bounding sphere against the view first, so that a city's thousands
// of objects out of view cost a few products each and build no parts (one whose sphere is
// under kFarPx pixels in radius is a single block); the lamps.
void CameraRenderer::Impl::BuildFrameScene(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                           std::optional<int> exclude) {
  const internal::StaticScene& scene = world->impl_->scene;
  frame_scene.Clear();
  const bool blink = internal::IndicatorsLit(std::chrono::duration<double>(frame.time_s));
  for (const RenderVehicle& car : frame.vehicles) {
    if (exclude && car.index == *exclude) continue;
    frame_scene.AddVehicle(car, blink, scene);
  }
  if (!frame.traffic.empty()) {
    constexpr double kFarPx = 6.0;
    const internal::CameraRays& rays = raster.rays();
    const Eigen::Matrix3d R_CM = X_MC.linear().transpose();
    const Eigen::Vector3d p_MC = X_MC.translation();
    for (const RenderTraffic& o : frame.traffic) {
      const Eigen::Vector3d centre_M = o.X_MO * Eigen::Vector3d(0, 0, o.size_m.z() / 2);
      const Eigen::Vector3d centre_C = R_CM * (centre_M - p_MC);
      const double radius = o.size_m.norm() / 2;
      if (!rays.SphereInView(centre_C, radius)) continue;
      frame_scene.AddTraffic(o, blink, rays.f_px * radius < kFarPx * centre_C.z());
      ++stats.traffic_in_view;
    }
  }
  frame_scene.SetLamps(frame.lamps);
}

void CameraRenderer::Impl::RenderOnce(const Eigen::Isometry3d& X_MC, const FrameState& frame,
                                      std::optional<int> exclude, std::uint8_t* target) {
  const auto t0 = std::chrono::steady_clock::now();
  raster.DrawGround(X_MC, target);
  const auto t1 = std::chrono::steady_clock::now();
  BuildFrameScene(X_MC, frame, exclude);
  raster.DrawParts(X_MC, frame_scene, target, stats);
  const auto t2 = std::chrono::steady_clock::now();
  stats.ground_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
  stats.objects_ms += std::chrono::duration<double, std::milli>(t2 - t1).count();
}

CameraRenderer::CameraRenderer(std::shared_ptr<const RenderWorld> world,
                               const camera::Intrinsics& intrinsics, const FilmOptions& film)
    : impl_(std::make_unique<Impl>(std::move(world), intrinsics, film)) {}

CameraRenderer::~CameraRenderer() = default;

const camera::CameraModel& CameraRenderer::model() const { return impl_->raster.rays().model; }
const FilmOptions& CameraRenderer::film() const { return impl_->film.options(); }
const RenderStats& CameraRenderer::stats() const { return impl_->stats; }

void CameraRenderer::Render(const Eigen::Isometry3d& X_MC, const FrameState& frame, Image& out,
                            std::optional<int> exclude, const Eigen::Vector3d& v_M_mps,
                            const Eigen::Vector3d& w_M_radps, std::uint64_t noise_seed) {
  Impl& m = *impl_;
  const FilmOptions& film = m.film.options();
  m.stats = {};
  out.width_px = m.raster.rays().w;
  out.height_px = m.raster.rays().h;
  const std::size_t bytes = m.colour.size();
  out.rgb.resize(bytes);
  if (film.exposure_time_s > 0) {
    // Motion blur: sub-frames at instants spread over the exposure, the vehicles and the camera
    // moved rigidly by their velocities.
    const std::chrono::duration<double> exposure(film.exposure_time_s);
    const int n = film.motion_blur_samples;
    m.motion_blur.Begin(frame, bytes);
    for (int s = 0; s < n; ++s) {
      const auto dt = internal::MotionBlur::Offset(exposure, s, n);
      const FrameState sub = m.motion_blur.SubFrame(frame, dt);
      m.RenderOnce(internal::MotionBlur::Shift(X_MC, v_M_mps, w_M_radps, dt), sub, exclude,
                   m.colour.data());
      m.motion_blur.Add(m.colour);
    }
    m.motion_blur.Average(n, out.rgb);
  } else {
    m.RenderOnce(X_MC, frame, exclude, out.rgb.data());
  }
  const auto film0 = std::chrono::steady_clock::now();
  m.film.Develop(out, noise_seed);
  m.stats.film_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - film0).count();
}

}  // namespace autodrive::vehicle_sim
