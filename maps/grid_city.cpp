#include "maps/grid_city.h"

#include "common/error.h"

namespace autodrive::maps {

Layout GridCity(int rows, int cols, const std::string& control) {
  AUTODRIVE_THROW_UNLESS(
      rows >= 1 && rows <= 200 && cols >= 1 && cols <= 200,
      "a grid city has 1 to 200 rows and columns of intersections, got " << rows << " x " << cols);
  AUTODRIVE_THROW_UNLESS(control == "signal" || control == "stop" || control == "mixed",
                         "control must be signal, stop or mixed, got \"" << control << "\"");
  Layout l;
  l.name = "grid_" + std::to_string(rows) + "x" + std::to_string(cols);
  const int tr = 2 * rows + 1;
  const int tc = 2 * cols + 1;
  for (int r = 0; r < tr; ++r) {
    std::vector<Cell> row;
    for (int c = 0; c < tc; ++c) {
      Cell cell;
      const bool odd_r = r % 2 == 1;
      const bool odd_c = c % 2 == 1;
      if (odd_r && odd_c) {
        cell.type = ModuleType::kIntersection;
        const bool signal = control == "signal" || (control == "mixed" && (r / 2 + c / 2) % 2 == 0);
        cell.control = signal ? Control::kSignal : Control::kStop;
      } else if (odd_r) {
        cell.type = ModuleType::kStraight;  // west-east between intersections
      } else if (odd_c) {
        cell.type = ModuleType::kStraight;  // north-south
        cell.rotation_deg = 90;
      }
      row.push_back(cell);
    }
    l.grid.push_back(row);
  }
  return l;
}

}  // namespace autodrive::maps
