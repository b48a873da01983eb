#include "traffic/nema/call_script.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "common/error.h"

namespace autodrive::traffic::nema {

bool CallScript::Called(std::uint32_t phase, Duration t) const {
  for (const PhaseCall& c : calls) {
    if (c.phase == phase && c.on <= t && (!c.off || t < *c.off)) return true;
  }
  return false;
}

CallScript ParseCallScript(const std::string& text, const std::string& source) {
  CallScript out;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string s; words >> s;) w.push_back(s);
    if (w.empty()) continue;
    const std::string where = source + ":" + std::to_string(number);
    AUTODRIVE_THROW_UNLESS(w.size() == 2 || w.size() == 3,
                           where << ": expected \"phase on_s [off_s]\", got \"" << line << "\"");
    const auto number_of = [&](const std::string& word, const char* what) {
      std::size_t used = 0;
      double v = 0;
      try {
        v = std::stod(word, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      AUTODRIVE_THROW_UNLESS(used == word.size() && std::isfinite(v),
                             where << ": " << what << " must be a number, got \"" << word << "\"");
      return v;
    };
    const double phase = number_of(w[0], "the phase");
    AUTODRIVE_THROW_UNLESS(phase >= 1 && phase <= 8 && phase == std::floor(phase),
                           where << ": the phase must be a NEMA phase number 1..8, got " << w[0]);
    PhaseCall call;
    call.phase = static_cast<std::uint32_t>(phase);
    const double on = number_of(w[1], "on_s");
    AUTODRIVE_THROW_UNLESS(on >= 0, where << ": on_s must be >= 0, got " << w[1]);
    call.on = FromSeconds(on);
    if (w.size() == 3) {
      const double off = number_of(w[2], "off_s");
      AUTODRIVE_THROW_UNLESS(off > on,
                             where << ": off_s must be after on_s (" << w[1] << "), got " << w[2]);
      call.off = FromSeconds(off);
    }
    out.calls.push_back(call);
  }
  return out;
}

CallScript LoadCallScript(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  AUTODRIVE_THROW_UNLESS(in.good(), path.string() << ": cannot read the call script");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseCallScript(text.str(), path.string());
}

}  // namespace autodrive::traffic::nema
