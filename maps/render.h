#pragma once
/// @file
/// Pictures of a built map, for people: a PNG (drawn with OpenCV) and an SVG (pugixml) of the
/// same scene. Drawn, bottom to top: the ground and a faint tile grid, the road surface, parking
/// bays, lane markings (solid white at the kerb, dashed white between lanes of one direction,
/// dashed yellow between opposite directions; none on parking tiles), movement paths through
/// intersections (coloured by turn: straight blue, left magenta, right green, U-turn orange), lane
/// direction arrows, stop lines, obstacles (boxes orange, walls grey), signal heads (red, amber and
/// green lamps, amber at the head's position), signs (stop octagon, yield triangle, others a
/// circle, each with a letter), then the map's name above the map and a scale bar below it.
///
/// Image coordinates: the map's [0, cols T] x [0, rows T] is drawn `RenderOptions::margin_px`
/// from each edge of the image, north up (image rows grow southwards); see `MapToPixel`.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "maps/map.h"

namespace autodrive::maps {

/// How a map is drawn. A plain value type.
struct RenderOptions {
  /// Scale: pixels along one tile's edge (px), in [8, 1000].
  double pixels_per_tile = 120.0;
  /// Border around the map (px), in [0, 500]: the map's name is written in the top one and the
  /// scale bar drawn in the bottom one.
  int margin_px = 40;
  bool show_tile_grid = true;    ///< faint lines along the tile edges
  bool show_movements = true;    ///< the movement paths through intersections
  bool show_lane_arrows = true;  ///< an arrow at the middle of every lane
  /// The signal heads with their three lamps lit (off for a live picture that draws each
  /// head's current lamp itself, as the dashboard does).
  bool show_signal_heads = true;
  /// Only what is painted on the ground, as a camera sees it: the ground, road surface, parking
  /// bays, lane markings and stop lines. No tile grid, movements, arrows, obstacles, signal
  /// heads, signs or legend (the simulator's cameras draw those as solid objects); the margin
  /// is the ground's colour.
  bool ground_only = false;
  /// Anti-aliased edges (PNG and in-memory pictures; SVG leaves it to the viewer). Without,
  /// every shape covers the pixels whose centres it covers plus its outline, so regions that
  /// share an edge overlap there with no seam: for a caller that draws at a multiple of the
  /// resolution it needs and averages down.
  bool antialias = true;

  /// Throws `InputError` naming the option and the value seen when one is out of range.
  void Validate() const;
  bool operator==(const RenderOptions&) const = default;
};

/// The size of the picture of `map` in pixels, (width, height):
/// `2 margin_px + round(cols * pixels_per_tile)` by `2 margin_px + round(rows * pixels_per_tile)`.
/// @throws InputError if the options are invalid or a side would exceed 30000 px.
[[nodiscard]] Eigen::Vector2i ImageSizePx(const Map& map, const RenderOptions& options = {});

/// Where the map-frame point `p_M` (m) lands in the picture, in continuous pixel coordinates
/// (u right, v down; pixel (i, j) covers [i, i+1) x [j, j+1)): `u = margin + x s`,
/// `v = margin + (rows T - y) s` with `s = pixels_per_tile / T` px/m.
[[nodiscard]] Eigen::Vector2d MapToPixel(const Map& map, const RenderOptions& options,
                                         const Eigen::Vector2d& p_M);

/// Draws the map into a 24-bit colour PNG of `ImageSizePx` pixels at `path` (PNG whatever the
/// extension), replacing any file there.
/// @throws InputError if the options are invalid, the picture too big, or the file cannot be
/// written (naming the path and the reason).
void RenderPng(const Map& map, const std::string& path, const RenderOptions& options = {});

/// A picture in memory: `height_px` rows of `width_px` pixels, 3 bytes each in R, G, B order.
struct Picture {
  int width_px = 0;
  int height_px = 0;
  std::vector<std::uint8_t> rgb;
};

/// The picture `RenderPng` writes, in memory.
/// @throws InputError if the options are invalid or the picture too big.
[[nodiscard]] Picture RenderPicture(const Map& map, const RenderOptions& options = {});

/// Draws the same picture as `RenderPng` as an SVG text file at `path`, in the same pixel
/// coordinates: one `<path class="road">` per road-surface region (holes by the even-odd rule),
/// lines as `<polyline>`, shapes as `<polygon>`, `<circle>` and `<rect>`, and the map's name in
/// the `<title>` and a `<text>`; one element per line, indented by two spaces. The document is
/// built with pugixml, which escapes every name. Replaces any file there.
/// @throws InputError if the options are invalid, the picture too big, the map's name holds a
/// control character (which XML cannot carry; nothing is written then), or the file cannot be
/// written (naming the path and the reason).
void RenderSvg(const Map& map, const std::string& path, const RenderOptions& options = {});

}  // namespace autodrive::maps
