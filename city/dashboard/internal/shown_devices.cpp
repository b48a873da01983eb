#include "city/dashboard/internal/shown_devices.h"

#include "common/dds/message.h"

namespace autodrive::dashboard::internal {

bool ShownDevices::Changed(const msg::DeviceEntry& d) {
  std::lock_guard lock(mutex_);
  const std::string_view id = dds::View(d.device_id);
  auto it = shown_.find(id);
  if (it == shown_.end()) {
    it = shown_.emplace(std::string(id), DeviceShown{}).first;
  } else if (it->second.kind == d.kind && it->second.backend == d.backend &&
             it->second.health == d.health && it->second.mode == d.mode &&
             it->second.reported == d.reported && it->second.lost == d.lost &&
             it->second.host == dds::View(d.host) && it->second.detail == dds::View(d.detail)) {
    return false;
  }
  DeviceShown& shown = it->second;
  shown.kind = d.kind;
  shown.backend = d.backend;
  shown.health = d.health;
  shown.mode = d.mode;
  shown.reported = d.reported;
  shown.lost = d.lost;
  shown.host = dds::View(d.host);
  shown.detail = dds::View(d.detail);
  return true;
}

}  // namespace autodrive::dashboard::internal
