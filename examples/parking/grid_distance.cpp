#include "examples/parking/grid_distance.h"

#include <opencv2/imgproc.hpp>

namespace autodrive::examples {

std::vector<float> DistanceToOccupied(const maps::OccupancyGrid& grid) {
  cv::Mat free(grid.height, grid.width, CV_8U);
  for (int r = 0; r < grid.height; ++r) {
    for (int c = 0; c < grid.width; ++c) free.at<std::uint8_t>(r, c) = grid.IsFree(c, r) ? 255 : 0;
  }
  cv::Mat distance;
  cv::distanceTransform(free, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  std::vector<float> out(static_cast<std::size_t>(grid.width) *
                         static_cast<std::size_t>(grid.height));
  for (int r = 0; r < grid.height; ++r) {
    for (int c = 0; c < grid.width; ++c) {
      out[static_cast<std::size_t>(r) * static_cast<std::size_t>(grid.width) +
          static_cast<std::size_t>(c)] =
          distance.at<float>(r, c) * static_cast<float>(grid.resolution_m);
    }
  }
  return out;
}

}  // namespace autodrive::examples
