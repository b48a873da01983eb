#include "traffic/sumo_frame.h"

#include <cmath>
#include <numbers>

namespace autodrive::traffic {

double YawFromSumoAngle(double angle_deg) {
  return std::remainder(std::numbers::pi / 2 - angle_deg * std::numbers::pi / 180,
                        2 * std::numbers::pi);
}

double SumoAngleFromYaw(double yaw_rad) {
  const double a = 90.0 - yaw_rad * 180 / std::numbers::pi;
  return a - 360.0 * std::floor(a / 360.0);
}

}  // namespace autodrive::traffic
