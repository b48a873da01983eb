#include "examples/parking/parking_config.h"

namespace autodrive::examples {

ParkingConfig LoadParkingConfig(const std::string& path) {
  return config::LoadFile<ParkingConfig>(path);
}

}  // namespace autodrive::examples
