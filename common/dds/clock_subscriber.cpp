#include "common/dds/clock_subscriber.h"

#include <spdlog/spdlog.h>

#include "common/dds/conversions.h"

namespace autodrive::dds {

SimClockSubscriber::SimClockSubscriber(const Participant& participant, SimClock& clock)
    : clock_(clock), reader_(participant, topics::Clock()) {
  reader_.OnDataAvailable([this](Reader<msg::Clock>& reader) {
    Message<msg::Clock> m;
    while (reader.TakeOne(m)) {
      received_.fetch_add(1);
      try {
        if (!clock_.AdvanceTo(FromMsg(m->clock))) {
          rejected_.fetch_add(1);
          spdlog::warn("/clock went backwards to {}; ignored", ToString(FromMsg(m->clock)));
        }
      } catch (const InputError& e) {
        rejected_.fetch_add(1);
        spdlog::warn("malformed /clock message ignored: {}", e.what());
      }
    }
  });
}

}  // namespace autodrive::dds
