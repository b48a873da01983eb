#include "scm/core/device_table.h"

#include <algorithm>

namespace autodrive::scm {

DeviceTable::DeviceTable(const CityRuntime& runtime, Duration timeout, MonoTime now)
    : timeout_(timeout), last_sent_(now - kMinInterval), next_period_(now + kPeriod) {
  rows_.reserve(runtime.heads().size() + runtime.intersections().size());
  for (const auto& h : runtime.heads()) {
    index_.emplace(h.name, rows_.size());
    rows_.emplace_back().device_id = h.name;
  }
}

void DeviceTable::Take(const DeviceReportView& r, MonoTime now) {
  auto it = index_.find(r.device_id);
  if (it == index_.end()) {  // a monitor's first report: rows only grow
    it = index_.emplace(std::string(r.device_id), rows_.size()).first;
    rows_.emplace_back().device_id = r.device_id;
  }
  DeviceRow& row = rows_[it->second];
  const std::uint8_t health = ToWire(r.health);
  const bool same = row.reported && !row.lost && row.host == r.host && row.kind == r.kind &&
                    row.backend == r.backend && row.health == health && row.mode == r.mode &&
                    row.detail == r.detail;
  // The lamps a light shows change every few seconds and have their own topic, read live by
  // whoever draws them: in the table they go out with the period, not soon after (a 32x32
  // city's lamps would send the whole table five times a second).
  if (row.displayed_state != r.displayed_state) {
    row.displayed_state = r.displayed_state;
    ++revision_;
  }
  if (!same) {
    if (row.host != r.host) row.host = r.host;
    if (row.detail != r.detail) row.detail = r.detail;
    row.kind = r.kind;
    row.backend = r.backend;
    row.health = health;
    row.mode = r.mode;
    row.reported = true;
    row.lost = false;
    ++revision_;
    changed_ = true;
  }
  row.last_report = r.stamp;
  row.last_heard = now;
}

bool DeviceTable::Due(MonoTime now) const { return now >= next_deadline(); }

MonoTime DeviceTable::next_deadline() const {
  return changed_ ? std::min(next_period_, last_sent_ + kMinInterval) : next_period_;
}

void DeviceTable::Refresh(MonoTime now) {
  for (DeviceRow& row : rows_) {
    const bool lost = row.reported && now - row.last_heard > timeout_;
    if (lost != row.lost) {
      row.lost = lost;
      ++revision_;
    }
  }
  changed_ = false;
  last_sent_ = now;
  next_period_ = now + kPeriod;
}

}  // namespace autodrive::scm
