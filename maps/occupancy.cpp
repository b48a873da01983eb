#include "maps/occupancy.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "common/error.h"

namespace autodrive::maps {

namespace {

constexpr double kMaxCells = 1e8;
// Cells are shrunk by this fraction of their edge on each side before the test against an
// obstacle: contact along a cell's edge, or an overlap thinner than rounding, occupies nothing.
constexpr double kTouchTolerance = 1e-6;

// The row (or column) whose centre is the first at or above `v`, in cell units from the origin.
// Only a starting guess: callers test the centres themselves so that neighbouring edges agree.
int FirstCentreAtOrAbove(double v_cells) { return static_cast<int>(std::ceil(v_cells - 0.5)); }

// Sets to `value` every cell whose centre lies inside `rings` by the even-odd rule. Row centre
// y_r is "inside" an edge's span when min(y) <= y_r < max(y) (half-open, so a vertex on a row
// counts once); a cell (c, r) is inside when its centre x lies in [x_2k, x_2k+1) of the sorted
// crossings of row r.
void FillRings(const std::vector<const Polyline*>& rings, std::uint8_t value, OccupancyGrid& g) {
  double y_min = std::numeric_limits<double>::infinity();
  double y_max = -y_min;
  for (const Polyline* ring : rings) {
    for (const auto& p : *ring) {
      y_min = std::min(y_min, p.y());
      y_max = std::max(y_max, p.y());
    }
  }
  if (!(y_min < y_max)) return;
  const double res = g.resolution_m;
  const auto centre_y = [&](int r) { return g.origin_m.y() + (r + 0.5) * res; };
  const auto centre_x = [&](int c) { return g.origin_m.x() + (c + 0.5) * res; };
  const int row_lo = std::max(0, FirstCentreAtOrAbove((y_min - g.origin_m.y()) / res) - 1);
  const int row_hi = std::min(g.height - 1, FirstCentreAtOrAbove((y_max - g.origin_m.y()) / res));
  if (row_lo > row_hi) return;
  std::vector<std::vector<double>> crossings(static_cast<std::size_t>(row_hi - row_lo + 1));

  for (const Polyline* ring : rings) {
    const std::size_t n = ring->size();
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d& a = (*ring)[i];
      const Eigen::Vector2d& b = (*ring)[(i + 1) % n];
      if (a.y() == b.y()) continue;
      const double lo = std::min(a.y(), b.y());
      const double hi = std::max(a.y(), b.y());
      const double dx_dy = (b.x() - a.x()) / (b.y() - a.y());
      const int r0 = std::max(row_lo, FirstCentreAtOrAbove((lo - g.origin_m.y()) / res) - 1);
      const int r1 = std::min(row_hi, FirstCentreAtOrAbove((hi - g.origin_m.y()) / res) + 1);
      for (int r = r0; r <= r1; ++r) {
        const double y = centre_y(r);
        if (y < lo || y >= hi) continue;
        crossings[static_cast<std::size_t>(r - row_lo)].push_back(a.x() + (y - a.y()) * dx_dy);
      }
    }
  }

  for (int r = row_lo; r <= row_hi; ++r) {
    std::vector<double>& xs = crossings[static_cast<std::size_t>(r - row_lo)];
    std::sort(xs.begin(), xs.end());
    std::uint8_t* row = g.cells.data() + static_cast<std::ptrdiff_t>(r) * g.width;
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
      int c = std::max(0, FirstCentreAtOrAbove((xs[k] - g.origin_m.x()) / res) - 1);
      while (c < g.width && centre_x(c) < xs[k]) ++c;
      for (; c < g.width && centre_x(c) < xs[k + 1]; ++c) row[c] = value;
    }
  }
}

// `v` (a cell index as a real number, already rounded) as an index in [-1, n]: values beyond
// either end (or NaN) are clamped, so that a far-away obstacle gives an empty range.
int ClampIndex(double v, int n) {
  if (!(v > -1.0)) return -1;
  if (!(v < n)) return n;
  return static_cast<int>(v);
}

// Sets to `value` every cell whose square, shrunk by `eps` (m) on each side, meets an edge of
// the closed `ring` (a conservative "supercover" of its boundary). For each row, the edge is
// clipped to the row's shrunk band of y; the clipped piece is a segment whose x extent is an
// interval, and the cells whose shrunk x range meets that interval are exactly the cells of
// the row that the edge touches. Time: the number of cells touched, plus one per edge.
void MarkEdges(const Polyline& ring, double eps, std::uint8_t value, OccupancyGrid& g) {
  const double res = g.resolution_m;
  const double ox = g.origin_m.x();
  const double oy = g.origin_m.y();
  const std::size_t n = ring.size();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[(i + 1) % n];
    const double y_lo = std::min(a.y(), b.y());
    const double y_hi = std::max(a.y(), b.y());
    // Rows whose band [oy + r res + eps, oy + (r + 1) res - eps] meets [y_lo, y_hi].
    const int r0 = std::max(0, ClampIndex(std::ceil((y_lo - oy + eps) / res - 1), g.height));
    const int r1 =
        std::min(g.height - 1, ClampIndex(std::floor((y_hi - oy - eps) / res), g.height));
    for (int r = r0; r <= r1; ++r) {
      const double band_lo = std::max(y_lo, oy + r * res + eps);
      const double band_hi = std::min(y_hi, oy + (r + 1) * res - eps);
      if (band_lo > band_hi) continue;  // only by rounding at the ends of the range
      double x_lo = std::min(a.x(), b.x());
      double x_hi = std::max(a.x(), b.x());
      if (a.y() != b.y()) {
        // t along a -> b at the band's ends; x is monotonic in t.
        const double dy = b.y() - a.y();
        const double t0 = std::clamp((band_lo - a.y()) / dy, 0.0, 1.0);
        const double t1 = std::clamp((band_hi - a.y()) / dy, 0.0, 1.0);
        const double x0 = a.x() + t0 * (b.x() - a.x());
        const double x1 = a.x() + t1 * (b.x() - a.x());
        x_lo = std::min(x0, x1);
        x_hi = std::max(x0, x1);
      }
      // Columns whose range [ox + c res + eps, ox + (c + 1) res - eps] meets [x_lo, x_hi].
      const int c0 = std::max(0, ClampIndex(std::ceil((x_lo - ox + eps) / res - 1), g.width));
      const int c1 =
          std::min(g.width - 1, ClampIndex(std::floor((x_hi - ox - eps) / res), g.width));
      if (c0 > c1) continue;
      std::uint8_t* row = g.cells.data() + static_cast<std::ptrdiff_t>(r) * g.width;
      std::fill(row + c0, row + c1 + 1, value);
    }
  }
}

// The shortest decimal text that reads back as `v`, e.g. "0.05", "2.0".
std::string Number(double v) {
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), v);
  AUTODRIVE_CHECK(ec == std::errc());
  std::string s(buffer, end);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// `text` as a YAML scalar: plain when it is made of safe characters, else double-quoted.
std::string YamlScalar(const std::string& text) {
  const bool plain = !text.empty() && std::all_of(text.begin(), text.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) != 0 || ch == '_' || ch == '-' ||
           ch == '.' || ch == '/';
  });
  if (plain) return text;
  std::string out = "\"";
  for (char ch : text) {
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out + "\"";
}

void WriteFile(const std::string& path, const std::string& what, const std::string& bytes) {
  errno = 0;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (out) out.close();
  if (!out) {
    const std::string reason = errno != 0 ? std::strerror(errno) : "write failed";
    throw InputError("cannot write the " + what + " \"" + path + "\": " + reason);
  }
}

}  // namespace

std::uint8_t OccupancyGrid::at(int col, int row) const {
  AUTODRIVE_CHECK(
      col >= 0 && col < width && row >= 0 && row < height,
      "cell (" << col << ", " << row << ") outside a " << width << "x" << height << " grid");
  return cells[static_cast<std::size_t>(row) * static_cast<std::size_t>(width) +
               static_cast<std::size_t>(col)];
}

Eigen::Vector2d OccupancyGrid::CellCentre(int col, int row) const {
  return origin_m + Eigen::Vector2d(col + 0.5, row + 0.5) * resolution_m;
}

std::size_t OccupancyGrid::FreeCount() const {
  return static_cast<std::size_t>(std::count(cells.begin(), cells.end(), kFree));
}

OccupancyGrid MakeOccupancyGrid(const Map& map, double resolution_m, bool road_only) {
  AUTODRIVE_THROW_UNLESS(
      std::isfinite(resolution_m) && resolution_m > 0,
      "the occupancy grid resolution must be a finite number > 0 m, got " << resolution_m);
  const Eigen::Vector2d size = map.size_m();
  // A map whose size is a whole number of cells gets exactly that many, despite rounding.
  const double cols = std::ceil(size.x() / resolution_m - 1e-9);
  const double rows = std::ceil(size.y() / resolution_m - 1e-9);
  AUTODRIVE_THROW_UNLESS(cols * rows <= kMaxCells, "the occupancy grid resolution "
                                                       << resolution_m << " m is too fine for a "
                                                       << size.x() << " x " << size.y()
                                                       << " m map: " << cols << " x " << rows
                                                       << " cells, more than 100 million");
  OccupancyGrid g;
  g.resolution_m = resolution_m;
  g.origin_m = Eigen::Vector2d::Zero();
  g.width = std::max(1, static_cast<int>(cols));
  g.height = std::max(1, static_cast<int>(rows));
  g.cells.assign(static_cast<std::size_t>(g.width) * static_cast<std::size_t>(g.height),
                 road_only ? OccupancyGrid::kOccupied : OccupancyGrid::kFree);
  if (road_only) {
    // The road side: a cell is free when its centre is on the drivable area. The drivable
    // regions are disjoint, so even-odd over all their rings is their union.
    std::vector<const Polyline*> rings;
    for (const Region& region : map.drivable) {
      rings.push_back(&region.outer);
      for (const Polyline& hole : region.holes) rings.push_back(&hole);
    }
    FillRings(rings, OccupancyGrid::kFree, g);
  }
  // The obstacle side, conservative: a cell the footprint touches is occupied. If no edge of
  // the footprint meets the (shrunk) cell, the cell is wholly inside or wholly outside the
  // footprint, and its centre tells which; so edges plus centres give exactly the cells that
  // the closed footprint meets.
  const double eps = kTouchTolerance * resolution_m;
  for (const Obstacle& o : map.obstacles) {
    if (o.footprint.empty()) continue;
    FillRings({&o.footprint}, OccupancyGrid::kOccupied, g);
    MarkEdges(o.footprint, eps, OccupancyGrid::kOccupied, g);
  }
  return g;
}

void WriteOccupancyGrid(const OccupancyGrid& grid, const std::string& pgm_path,
                        const std::string& yaml_path) {
  AUTODRIVE_CHECK(
      grid.width > 0 && grid.height > 0 &&
          grid.cells.size() ==
              static_cast<std::size_t>(grid.width) * static_cast<std::size_t>(grid.height),
      "a " << grid.width << "x" << grid.height << " grid with " << grid.cells.size() << " cells");
  std::string pgm = "P5\n# CREATOR: autodrive maps " + Number(grid.resolution_m) + " m/pix\n" +
                    std::to_string(grid.width) + " " + std::to_string(grid.height) + "\n255\n";
  const std::size_t header = pgm.size();
  const auto w = static_cast<std::size_t>(grid.width);
  pgm.resize(header + grid.cells.size());
  for (int r = 0; r < grid.height; ++r) {
    // PGM row 0 is the north edge: the grid's last row.
    const std::size_t src = static_cast<std::size_t>(grid.height - 1 - r) * w;
    const std::size_t dst = header + static_cast<std::size_t>(r) * w;
    for (std::size_t c = 0; c < w; ++c) {
      pgm[dst + c] = grid.cells[src + c] == OccupancyGrid::kFree ? '\xfe' : '\0';
    }
  }

  namespace fs = std::filesystem;
  const fs::path yaml_dir = fs::absolute(fs::path(yaml_path)).parent_path().lexically_normal();
  const fs::path image =
      fs::absolute(fs::path(pgm_path)).lexically_normal().lexically_proximate(yaml_dir);
  const std::string yaml = "image: " + YamlScalar(image.string()) + "\n" +
                           "resolution: " + Number(grid.resolution_m) + "\n" + "origin: [" +
                           Number(grid.origin_m.x()) + ", " + Number(grid.origin_m.y()) +
                           ", 0.0]\n" +
                           "negate: 0\n"
                           "occupied_thresh: 0.65\n"
                           "free_thresh: 0.196\n"
                           "mode: trinary\n";
  WriteFile(pgm_path, "occupancy grid image", pgm);
  WriteFile(yaml_path, "occupancy grid YAML", yaml);
}

}  // namespace autodrive::maps
