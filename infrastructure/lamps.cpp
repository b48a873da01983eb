#include "infrastructure/lamps.h"

namespace autodrive::infrastructure {

std::string_view ToString(Lamp lamp) {
  switch (lamp) {
    case Lamp::kRed:
      return "red";
    case Lamp::kYellow:
      return "yellow";
    case Lamp::kGreen:
      return "green";
  }
  return "?";
}

std::optional<Lamp> LampFromString(std::string_view text) {
  for (const Lamp lamp : kAllLamps) {
    if (ToString(lamp) == text) return lamp;
  }
  return std::nullopt;
}

bool Lamps::lit(Lamp lamp) const {
  switch (lamp) {
    case Lamp::kRed:
      return red;
    case Lamp::kYellow:
      return yellow;
    case Lamp::kGreen:
      return green;
  }
  return false;
}

void Lamps::set(Lamp lamp, bool on) {
  switch (lamp) {
    case Lamp::kRed:
      red = on;
      break;
    case Lamp::kYellow:
      yellow = on;
      break;
    case Lamp::kGreen:
      green = on;
      break;
  }
}

Lamps LampsFor(Aspect aspect, bool on) {
  Lamps lamps;
  switch (aspect) {
    case Aspect::kOff:
      break;
    case Aspect::kRed:
      lamps.red = true;
      break;
    case Aspect::kYellow:
      lamps.yellow = true;
      break;
    case Aspect::kGreen:
      lamps.green = true;
      break;
    case Aspect::kFlashingRed:
      lamps.red = on;
      break;
    case Aspect::kFlashingYellow:
      lamps.yellow = on;
      break;
  }
  return lamps;
}

std::int32_t StateWire(const Lamps& lamps) {
  if (lamps.green) return ToWire(Aspect::kGreen);
  if (lamps.yellow) return ToWire(Aspect::kYellow);
  if (lamps.red) return ToWire(Aspect::kRed);
  return ToWire(Aspect::kOff);
}

std::string ToString(const Lamps& lamps) {
  std::string text = "---";
  if (lamps.red) text[0] = 'R';
  if (lamps.yellow) text[1] = 'Y';
  if (lamps.green) text[2] = 'G';
  return text;
}

}  // namespace autodrive::infrastructure
