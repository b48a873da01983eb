#include "scm/io/device_inbox.h"

#include "autodrive_msgs/msg/DeviceStatus.h"

#include "common/dds/conversions.h"
#include "common/dds/topics.h"

namespace autodrive::scm {

DeviceReportView ReceivedReport::View() const {
  DeviceReportView r;
  r.device_id = device_id;
  r.city = city;
  r.host = host;
  r.health = health;
  r.displayed = displayed;
  r.last_command_id = last_command_id;
  r.detail = detail;
  r.kind = kind;
  r.backend = backend;
  r.mode = mode;
  r.displayed_state = displayed_state;
  r.stamp = stamp;
  return r;
}

DeviceStatusInbox::DeviceStatusInbox(const dds::Participant& participant, const Clock& clock)
    : clock_(clock) {
  // Every light and monitor has its own keep-last-1 writer on this keyless topic: the reader
  // keeps more, or one device's status would push out another's before the listener runs.
  reader_ = std::make_unique<dds::Reader<msg::DeviceStatus>>(
      participant, dds::topics::Devices().name, dds::Qos::LatchedState(4096));
  reader_->OnDataAvailable([this](dds::Reader<msg::DeviceStatus>&) { Poll(); });
  Poll();  // what came before the listener was set
}

DeviceStatusInbox::~DeviceStatusInbox() {
  // Detach the listener while `reader_` still points at the reader: detaching waits for a
  // running one, which takes through `reader_`. (unique_ptr::reset nulls the pointer before it
  // deletes the reader, so a listener still running in the deletion took through a null
  // pointer: the SCM's segfaults in Cyclone's recvUC thread at 0x24 as it stopped.)
  reader_->OnDataAvailable({});
  reader_.reset();
}

void DeviceStatusInbox::Poll() {
  std::lock_guard lock(mutex_);
  while (reader_->TakeOne(sample_)) {
    // The receipt time, read as soon as the sample is in hand.
    const MonoTime received = clock_.Read().mono;
    const msg::DeviceStatus& m = *sample_;
    const std::string_view id = dds::View(m.device_id);
    const std::string_view city = dds::View(m.city);
    const std::string_view host = dds::View(m.host);
    if (id.size() > kMaxDeviceIdBytes || city.size() > kMaxCityBytes ||
        host.size() > kMaxHostBytes || !DeviceHealthFromWire(m.health)) {
      malformed_.fetch_add(1);
      continue;
    }
    key_.assign(id);
    key_.push_back('\0');
    key_.append(host);
    key_.push_back('\0');
    key_.append(city);
    std::size_t slot = 0;
    if (const auto it = index_.find(key_); it != index_.end()) {
      slot = it->second;
    } else {
      if (slots_.size() >= kMaxDevices) {
        dropped_.fetch_add(1);
        continue;
      }
      slot = slots_.size();
      slots_.emplace_back();
      fresh_.push_back(0);
      index_.emplace(key_, slot);
    }
    ReceivedReport& r = slots_[slot];
    r.device_id.assign(id);
    r.city.assign(city);
    r.host.assign(host);
    r.detail.assign(dds::View(m.detail).substr(0, kMaxDetailBytes));
    r.health = *DeviceHealthFromWire(m.health);
    r.displayed = AspectFromWire(m.displayed_state);
    r.last_command_id = m.last_command_id;
    r.kind = m.kind;
    r.backend = m.backend;
    r.mode = m.mode;
    r.displayed_state = m.displayed_state;
    r.stamp = dds::FromMsg(m.header.stamp);
    r.received = received;
    if (!fresh_[slot]) {
      fresh_[slot] = 1;
      fresh_list_.push_back(slot);
    }
  }
}

std::size_t DeviceStatusInbox::Drain(std::vector<ReceivedReport>& out) {
  std::lock_guard lock(mutex_);
  const std::size_t n = fresh_list_.size();
  if (out.size() < n) out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t slot = fresh_list_[i];
    out[i] = slots_[slot];  // copy-assigns: the strings reuse out's memory
    fresh_[slot] = 0;
  }
  fresh_list_.clear();
  return n;
}

}  // namespace autodrive::scm
