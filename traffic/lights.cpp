#include "traffic/lights.h"

#include <algorithm>

#include "common/error.h"
#include "scm/core/city.h"

namespace autodrive::traffic {

namespace {

constexpr int kOff = 0;
constexpr int kRed = 1;
constexpr int kYellow = 2;
constexpr int kGreen = 3;

// How restrictive an aspect is, for heads that disagree: the larger wins.
int Restriction(Aspect a) {
  switch (a) {
    case Aspect::kGreen:
      return 0;
    case Aspect::kFlashingYellow:
      return 1;
    case Aspect::kYellow:
      return 2;
    case Aspect::kUnknown:
    case Aspect::kDark:
    case Aspect::kFlashingRed:
      return 3;
    case Aspect::kRed:
      return 4;
  }
  return 4;
}

// Per movement of `x` (by index): the indices of the movements it conflicts with.
std::vector<std::vector<std::size_t>> Foes(const maps::Intersection& x) {
  std::vector<std::vector<std::size_t>> foes(x.movements.size());
  const auto index = [&](MovementId m) {
    return static_cast<std::size_t>(std::find(x.movements.begin(), x.movements.end(), m) -
                                    x.movements.begin());
  };
  for (const auto& [a, b] : x.conflicts) {
    foes[index(a)].push_back(index(b));
    foes[index(b)].push_back(index(a));
  }
  return foes;
}

}  // namespace

bool HeadReading::Report(int lamp, MonoTime now) {
  if (seen_ && lamp == lamp_) return false;
  before_ = seen_ ? lamp_ : lamp;  // the first report has no history: steady
  before_since_ = seen_ ? since_ : now;
  seen_ = true;
  lamp_ = lamp;
  since_ = now;
  return true;
}

bool HeadReading::MayFlash() const { return seen_ && (lamp_ == kOff || before_ == kOff); }

Aspect HeadReading::Read(MonoTime now, Duration flash_window) const {
  if (!seen_) return Aspect::kUnknown;
  const bool recent = now - since_ < flash_window;
  switch (lamp_) {
    case kRed:
      return recent && before_ == kOff ? Aspect::kFlashingRed : Aspect::kRed;
    case kYellow:
      return recent && before_ == kOff ? Aspect::kFlashingYellow : Aspect::kYellow;
    case kGreen:
      return Aspect::kGreen;
    default:
      // Dark: after a colour shown for less than a flash window, the head is flashing it.
      if (recent && since_ - before_since_ < flash_window) {
        if (before_ == kRed) return Aspect::kFlashingRed;
        if (before_ == kYellow) return Aspect::kFlashingYellow;
      }
      return Aspect::kDark;
  }
}

char LinkState(Aspect aspect, bool foe_green) {
  switch (aspect) {
    case Aspect::kGreen:
      return foe_green ? 'g' : 'G';
    case Aspect::kYellow:
      return 'y';
    case Aspect::kRed:
      return 'r';
    case Aspect::kFlashingYellow:
      return 'o';
    case Aspect::kUnknown:
    case Aspect::kDark:
    case Aspect::kFlashingRed:
      return 's';
  }
  return 'r';
}

LightBinding::LightBinding(const scm::City& city) {
  const maps::Map& map = city.map;
  for (const scm::IntersectionModel& model : city.intersections) {
    const maps::Intersection& x = map.intersection(model.id);
    Light light;
    light.tls = x.name;
    for (const MovementId mid : x.movements) {
      const maps::Movement& m = map.movement(mid);
      const auto g = model.GroupOfMovement(mid);
      AUTODRIVE_THROW_UNLESS(g.has_value(), "intersection " << x.name << ": movement " << m.name
                                                            << " is in no signal group");
      const scm::SignalGroup& group = model.groups[*g];
      std::vector<SignalHeadId> facing, all;
      for (const SignalHeadId h : group.heads) {
        all.push_back(h);
        if (map.signal_head(h).approach == m.from_approach) facing.push_back(h);
      }
      AUTODRIVE_THROW_UNLESS(!all.empty(), "intersection " << x.name << ": movement " << m.name
                                                           << " is shown by no head");
      light.heads.push_back(facing.empty() ? all : facing);
      for (const SignalHeadId h : all) heads_.push_back(h);
    }
    light.foes = Foes(x);
    lights_.push_back(std::move(light));
  }
  for (const maps::Intersection& x : map.intersections) {
    if (x.control != maps::Control::kStop) continue;
    Light light;
    light.tls = x.name;
    light.stop_controlled = true;
    light.heads.resize(x.movements.size());
    light.foes = Foes(x);
    lights_.push_back(std::move(light));
  }
  std::sort(heads_.begin(), heads_.end());
  heads_.erase(std::unique(heads_.begin(), heads_.end()), heads_.end());
}

std::string LightBinding::State(std::size_t i, const std::vector<HeadReading>& readings,
                                MonoTime now, Duration flash_window) const {
  const Light& light = lights_.at(i);
  if (light.stop_controlled) return std::string(light.heads.size(), 's');
  std::vector<Aspect> aspects(light.heads.size(), Aspect::kGreen);
  for (std::size_t link = 0; link < light.heads.size(); ++link) {
    for (const SignalHeadId h : light.heads[link]) {
      const Aspect a = readings.at(h.value()).Read(now, flash_window);
      if (Restriction(a) > Restriction(aspects[link])) aspects[link] = a;
    }
  }
  std::string state(aspects.size(), 'r');
  for (std::size_t link = 0; link < aspects.size(); ++link) {
    const bool foe_green = std::any_of(light.foes[link].begin(), light.foes[link].end(),
                                       [&](std::size_t f) { return aspects[f] == Aspect::kGreen; });
    state[link] = LinkState(aspects[link], foe_green);
  }
  return state;
}

}  // namespace autodrive::traffic
