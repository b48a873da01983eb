#pragma once
/// @file
/// The renderer's scene (internal to vehicle_sim/renderer.cpp): what is in the world to be
/// drawn, and nothing of how. The static scene is built once from the map and the world's
/// geometry (the ground's picture and its mip pyramid, the solid parts, the tag bitmaps); the
/// frame's scene is rebuilt each (sub-)frame from the moving things (vehicles, background
/// traffic, the lamps). No camera, no pixels: the raster (raster.h) draws these parts, the film
/// (film.h) develops the picture.

#include <array>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "vehicle_sim/renderer.h"

namespace autodrive::vehicle_sim::internal {

inline constexpr Rgb kFloor{150, 146, 140};     ///< the lab's floor around the map
inline constexpr Rgb kLabWalls{208, 210, 214};  ///< above the horizon
inline constexpr Rgb kPlateColour{255, 255, 255};
inline constexpr Rgb kTagBlack{0, 0, 0};

/// A tag family's bitmap of one tag: `total` x `total` cells, row-major from the top-left,
/// 1 for white.
struct TagBitmap {
  int total = 0;
  int at_border = 0;
  std::vector<std::uint8_t> white;
};

/// The ground's picture and its mip pyramid in one RGB atlas image, so that one `cv::remap`
/// samples every pixel at its own level: level 0 at the atlas' left, levels 1, 2, ... stacked
/// down a column to its right. Level k's texel (i, j) covers level 0's texels
/// [2^k i, 2^k (i + 1)) x [2^k j, 2^k (j + 1)); every level has a border of the lab's floor at
/// least a texel wide, and a patch of the lab's walls sits below the last level.
struct GroundPyramid {
  double texel_m = 0.002;
  double x0_m = 0.0;  ///< map x of level 0's left edge
  double y1_m = 0.0;  ///< map y of level 0's top edge
  struct Level {
    int w = 0, h = 0;  ///< texels
    int x = 0, y = 0;  ///< where it is in the atlas
  };
  std::vector<Level> levels;
  cv::Mat atlas;  ///< CV_8UC3, R G B; its pixels in `atlas_memory`
  /// Aligned to 2 MiB and advised to the kernel as huge pages: a camera's rows walk the atlas
  /// in any direction, and with 4 KiB pages nearly every texel read would miss the TLB.
  std::unique_ptr<std::uint8_t, decltype(&std::free)> atlas_memory{nullptr, &std::free};
  Eigen::Vector2f walls{0, 0};  ///< atlas coordinates of a texel of the walls' colour
  cv::Mat atlas32;              ///< the atlas as R G B X words (CV_8UC4), for the AVX2 sampler
  bool avx2 = false;  ///< the AVX2 sampler may be used (built in, the CPU has it, allowed)
};

/// What is drawn on a face.
enum class Decal : std::uint8_t {
  kNone,
  kTag,           ///< the part's tag bitmap over the whole face (+z)
  kLamps,         ///< a signal head's three lamps (+x face)
  kVehicleFront,  ///< headlights and front indicators (+x face)
  kVehicleRear,   ///< tail lights and rear indicators (-x face)
  kSign,          ///< a sign's disc (+x face)
  kTrafficEnds,   ///< a background object's lamps: front (+x face) and rear (-x face)
};

/// A solid part: a box (half extents) or a vertical cylinder (radius, half height) in its own
/// frame B.
struct RenderPart {
  bool cylinder = false;
  Eigen::Matrix3d R_MB = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_MB = Eigen::Vector3d::Zero();
  Eigen::Vector3d half = Eigen::Vector3d::Zero();  ///< box: half extents; cylinder: r, r, hz
  Rgb colour;
  Decal decal = Decal::kNone;
  const TagBitmap* tag = nullptr;
  int head = -1;     ///< kLamps: index of the head in the map
  Rgb decal_colour;  ///< kSign: the disc's colour
  /// Vehicles: bit 0 headlights, 1 left, 2 right indicator lit now, 3 brake lights.
  std::uint8_t lights = 0;
  std::array<double, 3> lamp_z{};  ///< kLamps: heights of red, yellow, green in B
  double lamp_radius = 0.0;
  /// A tile of raised or sloping ground: the plane z' = a x' + b y' + c in B (axes along the
  /// map's), over the square |x'|, |y'| <= half.x(), textured with the ground's picture.
  bool terrain = false;
  float a = 0, b = 0, c = 0;
};

/// The bitmap of a tag. @throws InputError for an unknown family or id.
[[nodiscard]] TagBitmap MakeTagBitmap(const TagSpec& spec);

/// Whether the AVX2 ground sampler is compiled in (AUTODRIVE_RENDER_AVX2 on x86-64) and the
/// CPU running this has AVX2 and FMA.
[[nodiscard]] bool Avx2SamplerAvailable();

/// The ground's picture of `map` at `texel_m` metres a texel, as a mip pyramid; `allow_avx2`:
/// prepare it for the AVX2 sampler where that is available. @throws InputError for a texel
/// that is not positive or gives a picture too small or too big.
[[nodiscard]] GroundPyramid MakeGround(const maps::Map& map, double texel_m, bool allow_avx2);

/// What does not move, prepared once (what `RenderWorld` holds). Immutable but for the cache
/// of tag bitmaps, which is guarded by its own mutex; neither copied nor moved (the parts point
/// at its bitmaps).
class StaticScene {
 public:
  /// @throws InputError as `RenderWorld`'s constructor says.
  StaticScene(const maps::Map& map, const StaticGeometry& geometry,
              const RenderWorldOptions& options);
  StaticScene(const StaticScene&) = delete;
  StaticScene& operator=(const StaticScene&) = delete;

  [[nodiscard]] const RenderWorldOptions& options() const { return options_; }
  [[nodiscard]] const GroundPyramid& ground() const { return ground_; }
  /// The static solid parts: obstacles, poles, heads, signs, ground tags.
  [[nodiscard]] const std::vector<RenderPart>& parts() const { return parts_; }
  /// The raised and sloping tiles and the blocks under them (drawn with the ground).
  [[nodiscard]] const std::vector<RenderPart>& terrain() const { return terrain_; }
  /// The map's signal heads' ids, ascending (a part's `head` indexes this).
  [[nodiscard]] const std::vector<SignalHeadId>& head_ids() const { return head_ids_; }
  /// Made on first use and kept; thread-safe. @throws InputError for an unknown family or id.
  [[nodiscard]] const TagBitmap& Tag(const TagSpec& spec) const;

 private:
  void AddObstacles(const maps::Map& map, const StaticGeometry& geometry);
  void AddTerrain(const TerrainModel& terrain);
  void AddHeads(const maps::Map& map, const TerrainModel& terrain);
  void AddSigns(const maps::Map& map, const TerrainModel& terrain);
  void AddGroundTags(const TerrainModel& terrain);

  RenderWorldOptions options_;
  GroundPyramid ground_;
  std::vector<RenderPart> parts_;
  std::vector<RenderPart> terrain_;
  std::vector<SignalHeadId> head_ids_;
  mutable std::mutex tags_mutex_;
  mutable std::map<std::pair<std::string, int>, std::unique_ptr<TagBitmap>> tags_;
};

/// Whether blinking indicators are lit at simulated time `t` (1.5 Hz, lit the first half).
[[nodiscard]] bool IndicatorsLit(std::chrono::duration<double> t);

/// The moving parts of one (sub-)frame: the vehicles' and the background traffic's parts and
/// which lamps are lit. Its buffers are kept from frame to frame (no allocation in steady
/// state). Copyable and movable as a value.
class FrameScene {
 public:
  /// For a world of the signal heads `head_ids` (ascending, as `StaticScene::head_ids`).
  explicit FrameScene(std::vector<SignalHeadId> head_ids);

  /// Drops the last frame's parts and lamps.
  void Clear();
  /// Adds a vehicle's parts (body, lights, LIDAR, wheels, roof tag) with its indicators lit
  /// when `blink`; tag bitmaps from `scene`.
  void AddVehicle(const RenderVehicle& car, bool blink, const StaticScene& scene);
  /// Adds a background object's parts; `far` (a few pixels across): one block in the roof's
  /// colour.
  void AddTraffic(const RenderTraffic& object, bool blink, bool far);
  /// Sets the lamps from the frame's (heads not listed are dark; unknown heads ignored).
  void SetLamps(std::span<const HeadLamps> lamps);

  [[nodiscard]] const std::vector<RenderPart>& parts() const { return parts_; }
  /// Per head (in the order of the head ids): bits red, yellow, green.
  [[nodiscard]] const std::vector<std::uint8_t>& lamp_state() const { return lamp_state_; }

 private:
  std::vector<RenderPart> parts_;
  std::vector<SignalHeadId> head_ids_;
  std::vector<std::uint8_t> lamp_state_;
};

}  // namespace autodrive::vehicle_sim::internal
