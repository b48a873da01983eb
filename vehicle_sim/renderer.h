#pragma once
/// @file
/// The simulated cameras' renderer: what a camera (common/camera) sees of the simulated world,
/// drawn in software on one CPU core, with no GPU and no window. See docs/camera.md.
///
/// Method: every pixel's ray (through the lens model, distortion included, computed once per
/// camera) is followed into the world, so straight edges bend exactly as the lens bends them
/// and nothing is approximated by resampling:
/// - the ground is the map's own picture (maps/render.h, `ground_only`) at `ground_texel_m`,
///   sampled bilinearly from a mip pyramid at the level of the pixel's footprint; the ground is
///   the plane z = 0 (ramps and raised tiles: see `RenderWorld`); off the map, the lab's floor;
///   above the horizon, the lab's walls;
/// - solid objects are boxes and vertical cylinders, each tested only inside its own bounding
///   rectangle in the image, nearest first by a depth buffer: the map's walls and boxes and any
///   unmapped obstacle (as the world has them), the poles of lights and signs, each light's head
///   with its red, yellow and green lamps lit as `signal_<i>/state` says, each sign's plate, and
///   every vehicle (body, wheels, LIDAR, headlights, indicators and tail lights, and its roof
///   AprilTag on a white plate), and the background traffic (a body and cabin of each object's
///   size, brake lights and indicators; objects out of view are dropped by their bounding
///   sphere before any of their parts is built);
/// - AprilTags are drawn from the AprilTag library's own family bitmaps, on the ground (fixed
///   reference tags) and on roofs; every pixel that sees a tag is supersampled (4 x 4 rays), so
///   the tag's edges fall where they are to a small fraction of a pixel;
/// - film effects, in order: a Lambertian light (ambient plus one directional light; lit lamps
///   and headlights emit), exposure, motion blur (the frame averaged over sub-frames spread over
///   the exposure time, the vehicles moved by their velocities), Gaussian blur, Gaussian noise.
///
/// Frames and units: the map frame M (x east, y north, z up; metres), the camera's optical frame
/// C as common/camera says. Images are rgb8, row-major, top row first.
///
/// Thread safety: a `RenderWorld` is immutable once built and may be shared by any number of
/// `CameraRenderer`s on any threads; one `CameraRenderer` renders on one thread at a time.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/camera/camera_model.h"
#include "common/ids.h"
#include "vehicle_sim/camera_config.h"
#include "vehicle_sim/raycast.h"
#include "vehicle_sim/vehicle_params.h"

namespace autodrive::maps {
struct Map;
}

namespace autodrive::vehicle_sim {

/// An image in memory: `height_px` rows of `width_px` pixels, R, G, B bytes each, top row first
/// (sensor_msgs/Image's rgb8 with step = 3 width).
struct Image {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> rgb;
};

/// A vehicle as the cameras see it, now.
struct RenderVehicle {
  int index = 0;  ///< the world's vehicle index (a camera on it excludes it)
  /// The vehicle frame V (middle of the rear axle on the ground; x forward, y left, z up).
  Eigen::Isometry3d X_MV = Eigen::Isometry3d::Identity();
  /// Velocity of V's origin and angular velocity, map frame: for motion blur.
  Eigen::Vector3d v_M_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_M_radps = Eigen::Vector3d::Zero();
  const VehicleParams* params = nullptr;  ///< its dimensions; not null
  VehicleLook look;
  bool headlights = false;
  bool left_indicator = false;   ///< blinking at 1.5 Hz while on
  bool right_indicator = false;  ///< (both on: hazard lights)
};

/// How a background object (`RenderTraffic`) is drawn.
enum class TrafficShape : std::uint8_t {
  kCar,    ///< a body up to 60% of the height and a shorter cabin on it (the roof's colour)
  kTall,   ///< one body up to the full height in the body's colour (buses, trucks)
  kBlock,  ///< one block of the whole size (two-wheelers, pedestrians)
};

/// The colour the cameras paint an unmapped obstacle (cardboard brown), standing from the start
/// (part of the static world) or for a while (drawn as a `TrafficShape::kBlock`).
inline constexpr Rgb kUnmappedObstacleColour{170, 120, 70};

/// A background traffic object (a SUMO vehicle) as the cameras see it, now: a box-ish body
/// that fills its size, standing on the ground.
struct RenderTraffic {
  /// Frame O: the centre of its footprint on the ground, x forward, z up (map frame).
  Eigen::Isometry3d X_MO = Eigen::Isometry3d::Identity();
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();  ///< length (along x), width, height
  double speed_mps = 0.0;                            ///< along O's x: for motion blur
  TrafficShape shape = TrafficShape::kCar;
  Rgb body;
  Rgb roof;
  bool brake = false;            ///< brake lights lit
  bool left_indicator = false;   ///< blinking at 1.5 Hz while on
  bool right_indicator = false;  ///< (both on: hazard lights)
};

/// Which lamps of a signal head are lit.
struct HeadLamps {
  SignalHeadId head{1};
  bool red = false;
  bool yellow = false;
  bool green = false;
};

/// The world's moving parts at one instant.
struct FrameState {
  double time_s = 0.0;  ///< simulated time: the indicators blink on it
  std::span<const RenderVehicle> vehicles;
  std::span<const HeadLamps> lamps;  ///< heads not listed are dark
  /// Background traffic. Each object is first tested by its bounding sphere against the view,
  /// so objects out of view cost a few multiplications each.
  std::span<const RenderTraffic> traffic;
};

/// How the static world is drawn.
struct RenderWorldOptions {
  /// Size of a texel of the ground's picture (m): 2 mm, so a 5 m map is a 2500 px texture.
  double ground_texel_m = 0.002;
  /// The poles, heads and signs: as the sensors see them (the same poles).
  StaticSceneOptions scene;
  /// Reference tags on the ground.
  std::vector<GroundTag> ground_tags;
  /// The ground is sampled with AVX2 where it is built in and the CPU has it (about twice as
  /// fast; `RenderAvx2Available()`); false forces the portable path (`cv::remap`), which gives
  /// the same picture to within a level or two.
  bool allow_avx2 = true;
};

namespace internal {
struct TagBitmap;
}  // namespace internal

/// Whether the AVX2 ground sampler can run here: it is built in (x86-64 with the CMake option
/// AUTODRIVE_RENDER_AVX2, on by default) and this CPU has AVX2 and FMA.
[[nodiscard]] bool RenderAvx2Available();

/// What does not move, prepared once: the ground's picture and its mip pyramid, the solid
/// static objects, the tag bitmaps. Immutable; share it between cameras.
class RenderWorld {
 public:
  /// From the map and the world's static geometry (`World::Scene().geometry()`: the map's
  /// obstacles as the world placed them, then unmapped ones; the poles). @throws InputError for
  /// a ground tag of an unknown family or an id the family does not have, or a prism that is
  /// not a rectangle.
  RenderWorld(const maps::Map& map, const StaticGeometry& geometry,
              const RenderWorldOptions& options = {});
  ~RenderWorld();
  RenderWorld(const RenderWorld&) = delete;
  RenderWorld& operator=(const RenderWorld&) = delete;

  [[nodiscard]] const RenderWorldOptions& options() const;
  /// Whether its ground is drawn by the AVX2 sampler: `options().allow_avx2` and
  /// `RenderAvx2Available()`.
  [[nodiscard]] bool uses_avx2() const;
  /// The bitmap of a tag: `total_width` x `total_width` cells, row-major from the top-left,
  /// true for a white cell. @throws InputError for an unknown family or id.
  [[nodiscard]] const internal::TagBitmap& Tag(const TagSpec& tag) const;

 private:
  friend class CameraRenderer;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A tag's four outer corners of its black square in the tag's own frame (m, z = 0): the
/// corner order of the AprilTag library's detections (counter-clockwise seen in the image, the
/// first at the bitmap's bottom-left), for tag frame x right and y up as `GroundTag` defines:
/// (-s/2, -s/2), (s/2, -s/2), (s/2, s/2), (-s/2, s/2).
[[nodiscard]] std::array<Eigen::Vector3d, 4> TagCorners(double size_m);

/// The pose of a vehicle's roof tag frame T in the map frame (see `VehicleLook`).
[[nodiscard]] Eigen::Isometry3d VehicleTagPose(const RenderVehicle& vehicle);

/// Where the last frame's time went (wall time of the rendering thread).
struct RenderStats {
  double ground_ms = 0;   ///< the ground (0.0x when a fixed camera's ground was reused)
  double objects_ms = 0;  ///< solid parts: placing and drawing them
  double film_ms = 0;     ///< exposure, blur, noise and motion blur's averaging
  int parts_drawn = 0;    ///< parts whose image rectangle was not empty (per sub-frame)
  /// Background objects whose bounding sphere met the view, whose parts were built (per
  /// sub-frame); the others cost their sphere's test only.
  int traffic_in_view = 0;
  std::int64_t pixels_tested = 0;  ///< pixel-part ray tests
};

/// Renders one camera. Holds the camera's rays (12 bytes a pixel) and its buffers.
class CameraRenderer {
 public:
  /// @throws InputError when the intrinsics are invalid.
  CameraRenderer(std::shared_ptr<const RenderWorld> world, const camera::Intrinsics& intrinsics,
                 const FilmOptions& film = {});
  ~CameraRenderer();
  CameraRenderer(const CameraRenderer&) = delete;
  CameraRenderer& operator=(const CameraRenderer&) = delete;

  [[nodiscard]] const camera::CameraModel& model() const;
  [[nodiscard]] const FilmOptions& film() const;
  /// Of the last `Render`.
  [[nodiscard]] const RenderStats& stats() const;

  /// Renders what the camera with optical frame pose `X_MC` (in the map frame) sees of
  /// `frame` into `out` (resized to the camera's image). `exclude` names the vehicle carrying
  /// the camera (not drawn). `v_M_mps` and `w_M_radps`: the camera's own motion, for motion
  /// blur. `noise_seed`: the noise of this frame (reproducible).
  void Render(const Eigen::Isometry3d& X_MC, const FrameState& frame, Image& out,
              std::optional<int> exclude = std::nullopt,
              const Eigen::Vector3d& v_M_mps = Eigen::Vector3d::Zero(),
              const Eigen::Vector3d& w_M_radps = Eigen::Vector3d::Zero(),
              std::uint64_t noise_seed = 0);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::vehicle_sim
