#include "traffic/lamp_inbox.h"

#include "common/dds/topics.h"

namespace autodrive::traffic {

LampInbox::LampInbox(const dds::Participant& participant, const std::vector<SignalHeadId>& heads) {
  readers_.reserve(heads.size());
  for (const SignalHeadId h : heads) {
    readers_.push_back(
        std::make_unique<dds::Reader<msg::Int32>>(participant, dds::topics::SignalState(h)));
    dds::Reader<msg::Int32>& reader = *readers_.back();
    reader.OnDataAvailable([this, h](dds::Reader<msg::Int32>& r) { Drain(h, r); });
    // What came before the listener was set (a latched report from a light already up).
    Drain(h, reader);
  }
}

LampInbox::~LampInbox() { readers_.clear(); }

void LampInbox::Drain(SignalHeadId head, dds::Reader<msg::Int32>& reader) {
  dds::Message<msg::Int32> m;
  std::lock_guard lock(mutex_);
  while (reader.TakeOne(m)) {
    arrived_.push_back(Lamp{head, m->data});
    received_.fetch_add(1);
  }
}

void LampInbox::Take(std::vector<Lamp>& out) {
  out.clear();
  std::lock_guard lock(mutex_);
  std::swap(out, arrived_);
}

}  // namespace autodrive::traffic
