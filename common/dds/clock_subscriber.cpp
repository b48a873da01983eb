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
        const Time t = FromMsg(m->clock);
        switch (clock_.AdvanceTo(t)) {
          case SimClock::Advance::kForward:
            break;
          case SimClock::Advance::kIgnored:
            rejected_.fetch_add(1);
            spdlog::warn("/clock went back a little to {} (reordered?); ignored", ToString(t));
            break;
          case SimClock::Advance::kRestarted:
            spdlog::warn("/clock went back to {}: the simulation restarted, new clock session {}",
                         ToString(t), clock_.restarts());
            break;
        }
      } catch (const InputError& e) {
        rejected_.fetch_add(1);
        spdlog::warn("malformed /clock message ignored: {}", e.what());
      }
    }
  });
}

}  // namespace autodrive::dds
