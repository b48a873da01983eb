#include "scenarios/internal/lamp_bands.h"

#include <cmath>

namespace autodrive::scenarios::internal {

std::vector<LampBand> LampBands(const std::vector<std::pair<double, int>>& changes, double end_s,
                                double flash_half_max_s) {
  // Plain stretches first.
  std::vector<LampBand> plain;
  for (std::size_t i = 0; i < changes.size(); ++i) {
    const double to = i + 1 < changes.size() ? changes[i + 1].first : end_s;
    if (to <= changes[i].first) continue;
    plain.push_back({changes[i].first, to, changes[i].second});
  }
  // Runs of short stretches alternating between off and one colour: flashing.
  std::vector<LampBand> out;
  const auto short_one = [&](const LampBand& b) { return b.to_s - b.from_s <= flash_half_max_s; };
  for (std::size_t i = 0; i < plain.size();) {
    std::size_t j = i;
    int colour = 0;
    while (j < plain.size() && short_one(plain[j])) {
      const int a = plain[j].aspect;
      if (a != 0) {
        if (a != 1 && a != 2) break;
        if (colour == 0) colour = a;
        if (a != colour) break;
      }
      if (j > i && a == plain[j - 1].aspect) break;
      ++j;
    }
    if (colour != 0 && j - i >= 3) {
      out.push_back({plain[i].from_s, plain[j - 1].to_s, colour == 1 ? 4 : 5});
      i = j;
    } else {
      out.push_back(plain[i]);
      ++i;
    }
  }
  // One band per aspect in a row.
  std::vector<LampBand> merged;
  for (const LampBand& b : out) {
    if (!merged.empty() && merged.back().aspect == b.aspect &&
        std::abs(merged.back().to_s - b.from_s) < 1e-9) {
      merged.back().to_s = b.to_s;
    } else {
      merged.push_back(b);
    }
  }
  return merged;
}

int AspectAt(const std::vector<LampBand>& bands, double t) {
  int aspect = 0;
  for (const LampBand& b : bands) {
    if (b.from_s > t + 1e-9) break;
    aspect = b.aspect;
  }
  return aspect;
}

}  // namespace autodrive::scenarios::internal
