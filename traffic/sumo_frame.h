#pragma once
/// @file
/// SUMO's angles and the map's: SUMO's navigational angle (degrees, 0 north, clockwise) and a
/// map yaw (rad, 0 east, counter-clockwise). Positions are SUMO's metres, the map's times
/// `TrafficNetwork::scale`.

namespace autodrive::traffic {

/// SUMO's navigational angle (degrees, 0 north, clockwise) as a map yaw (rad, 0 east, CCW).
[[nodiscard]] double YawFromSumoAngle(double angle_deg);
/// A map yaw as SUMO's navigational angle.
[[nodiscard]] double SumoAngleFromYaw(double yaw_rad);

}  // namespace autodrive::traffic
