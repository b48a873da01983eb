#include "maps/mesh.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>

#include <cmath>
#include <fstream>

#include "common/error.h"

namespace autodrive::maps {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<K::Point_3>;
using VertexIndex = Mesh::Vertex_index;

struct TileAt {
  int row, col;
};

TileAt Locate(const Map& map, double x, double y) {
  const Eigen::Vector2d size = map.size_m();
  AUTODRIVE_THROW_UNLESS(x >= 0 && y >= 0 && x <= size.x() && y <= size.y(),
                         "point (" << x << ", " << y << ") is outside the map [0, " << size.x()
                                   << "] x [0, " << size.y() << "]");
  const int col = std::min(map.cols - 1, static_cast<int>(x / map.tile_size_m));
  const int row_from_south = std::min(map.rows - 1, static_cast<int>(y / map.tile_size_m));
  return {map.rows - 1 - row_from_south, col};
}

double HeightInTile(const Map& map, int row, int col, double x, double y) {
  const auto i = static_cast<std::size_t>(row * map.cols + col);
  const double base = map.terrain.tile_elevation_m[i];
  const double rise = map.terrain.tile_rise_m[i];
  if (rise == 0.0) return base;
  // Fraction along the ramp's local +x (rotated counter-clockwise by its rotation).
  const double T = map.tile_size_m;
  const Eigen::Vector2d c = map.TileCentre({row, col});
  const double cx = c.x();
  const double cy = c.y();
  const double a = map.terrain.tile_rotation_deg[i] * kPi / 180.0;
  const double along = (x - cx) * std::cos(a) + (y - cy) * std::sin(a);
  return base + rise * std::clamp(along / T + 0.5, 0.0, 1.0);
}

}  // namespace

double TerrainHeight(const Map& map, double x_m, double y_m) {
  const TileAt t = Locate(map, x_m, y_m);
  return HeightInTile(map, t.row, t.col, x_m, y_m);
}

MeshStats WriteMeshObj(const Map& map, const std::string& path) {
  Mesh mesh;
  const double T = map.tile_size_m;
  for (int r = 0; r < map.rows; ++r) {
    for (int c = 0; c < map.cols; ++c) {
      const double x0 = c * T, x1 = (c + 1) * T;
      const double y0 = (map.rows - 1 - r) * T, y1 = y0 + T;
      // Heights just inside the tile, so that a ramp's corners take its own heights.
      const double e = 1e-9;
      const auto v = [&](double x, double y, double xi, double yi) {
        return mesh.add_vertex(K::Point_3(x, y, HeightInTile(map, r, c, xi, yi)));
      };
      const VertexIndex a = v(x0, y0, x0 + e, y0 + e), b = v(x1, y0, x1 - e, y0 + e);
      const VertexIndex cc = v(x1, y1, x1 - e, y1 - e), d = v(x0, y1, x0 + e, y1 - e);
      mesh.add_face(a, b, cc);
      mesh.add_face(a, cc, d);
    }
  }
  for (const auto& o : map.obstacles) {
    const double base = TerrainHeight(map, o.footprint[0].x(), o.footprint[0].y());
    std::vector<VertexIndex> lo, hi;
    for (const auto& p : o.footprint) {
      lo.push_back(mesh.add_vertex(K::Point_3(p.x(), p.y(), base)));
      hi.push_back(mesh.add_vertex(K::Point_3(p.x(), p.y(), base + o.height_m)));
    }
    const std::size_t n = o.footprint.size();
    mesh.add_face(hi[0], hi[1], hi[2]);  // top (footprints are counter-clockwise rectangles)
    mesh.add_face(hi[0], hi[2], hi[3]);
    mesh.add_face(lo[0], lo[2], lo[1]);  // bottom
    mesh.add_face(lo[0], lo[3], lo[2]);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = (i + 1) % n;
      mesh.add_face(lo[i], lo[j], hi[j]);
      mesh.add_face(lo[i], hi[j], hi[i]);
    }
  }
  std::ofstream out(path);
  AUTODRIVE_THROW_UNLESS(out.good(), path << ": cannot write the mesh file");
  out << "# AutoDRIVE map " << map.name << ": terrain and obstacles, map frame, metres, z up\n";
  out.precision(9);
  for (const VertexIndex vi : mesh.vertices()) {
    const auto& p = mesh.point(vi);
    out << "v " << p.x() << " " << p.y() << " " << p.z() << "\n";
  }
  for (const auto f : mesh.faces()) {
    out << "f";
    for (const VertexIndex vi : vertices_around_face(mesh.halfedge(f), mesh)) {
      out << " " << (static_cast<std::size_t>(vi) + 1);
    }
    out << "\n";
  }
  AUTODRIVE_THROW_UNLESS(out.good(), path << ": writing the mesh failed");
  return {mesh.number_of_vertices(), mesh.number_of_faces()};
}

}  // namespace autodrive::maps
