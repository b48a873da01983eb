#include "traffic/nema/call_script.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>

#include "common/error.h"

namespace autodrive::traffic::nema {

namespace {

// Seconds to the millisecond without trailing zeros: "12", "12.5", "0.125".
std::string Seconds(Duration d) {
  const auto ms = std::chrono::round<std::chrono::milliseconds>(d).count();
  std::string out = fmt::format("{}.{:03}", ms / 1000, std::abs(ms % 1000));
  while (out.back() == '0') out.pop_back();
  if (out.back() == '.') out.pop_back();
  return out;
}

// A uniform integer in [0, n) from `engine`, by rejection (the same on every machine, unlike
// std::uniform_int_distribution, whose algorithm each standard library chooses).
std::uint64_t Below(std::mt19937_64& engine, std::uint64_t n) {
  const std::uint64_t reject_below = (0 - n) % n;  // 2^64 mod n
  std::uint64_t x = engine();
  while (x < reject_below) x = engine();
  return x % n;
}

// The number of steps `d` is; checked to be whole and positive.
std::int64_t Steps(Duration d, Duration step, const char* what) {
  AUTODRIVE_THROW_UNLESS(d > Duration{0} && d % step == Duration{0},
                         "random calls: " << what << " must be a positive whole number of "
                                          << ToSeconds(step) << " s steps, got " << ToSeconds(d)
                                          << " s");
  return d / step;
}

}  // namespace

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

std::string CallScriptText(const CallScript& script, const std::string& header) {
  std::string out;
  std::istringstream lines(header);
  for (std::string line; std::getline(lines, line);) out += "# " + line + "\n";
  out += "# phase on_s off_s\n";
  for (const PhaseCall& c : script.calls) {
    out += fmt::format("{} {}{}\n", c.phase, Seconds(c.on), c.off ? " " + Seconds(*c.off) : "");
  }
  return out;
}

void Validate(const RandomCallParams& p, Duration step) {
  AUTODRIVE_THROW_UNLESS(step > Duration{0}, "random calls: the step must be > 0");
  AUTODRIVE_THROW_UNLESS(p.calls_from >= Duration{0} && p.calls_from % step == Duration{0},
                         "random calls: the start of the calls must be a whole number of "
                             << ToSeconds(step) << " s steps >= 0, got " << ToSeconds(p.calls_from)
                             << " s");
  (void)Steps(p.mean_gap, step, "the mean gap");
  const std::int64_t pass_min = Steps(p.pass_min, step, "the shortest passing occupancy");
  const std::int64_t pass_max = Steps(p.pass_max, step, "the longest passing occupancy");
  const std::int64_t queue_min = Steps(p.queue_min, step, "the shortest queue occupancy");
  const std::int64_t queue_max = Steps(p.queue_max, step, "the longest queue occupancy");
  AUTODRIVE_THROW_UNLESS(pass_min <= pass_max, "random calls: the shortest passing occupancy ("
                                                   << ToSeconds(p.pass_min)
                                                   << " s) is above the longest ("
                                                   << ToSeconds(p.pass_max) << " s)");
  AUTODRIVE_THROW_UNLESS(queue_min <= queue_max, "random calls: the shortest queue occupancy ("
                                                     << ToSeconds(p.queue_min)
                                                     << " s) is above the longest ("
                                                     << ToSeconds(p.queue_max) << " s)");
  AUTODRIVE_THROW_UNLESS(p.queue_share >= 0.0 && p.queue_share <= 1.0,
                         "random calls: the queue share must be in [0, 1], got " << p.queue_share);
}

CallScript RandomCallScript(const std::vector<std::uint32_t>& phases, std::uint64_t seed,
                            Duration duration, Duration step, const RandomCallParams& p) {
  Validate(p, step);
  const std::int64_t end = Steps(duration, step, "the duration");
  const std::int64_t gap = Steps(p.mean_gap, step, "the mean gap");
  const std::int64_t pass_min = p.pass_min / step;
  const std::int64_t pass_span = p.pass_max / step - pass_min + 1;
  const std::int64_t queue_min = p.queue_min / step;
  const std::int64_t queue_span = p.queue_max / step - queue_min + 1;
  // A vehicle arrives at a step when a draw is below 2^64 / gap (probability 1 / gap steps).
  const std::uint64_t arrives_below =
      std::numeric_limits<std::uint64_t>::max() / static_cast<std::uint64_t>(gap);
  // A queue when a draw is below queue_share * 2^64 (the double is exact in IEEE arithmetic for
  // every machine this runs on; 1.0 maps to every draw).
  const std::uint64_t queue_below = p.queue_share >= 1.0
                                        ? std::numeric_limits<std::uint64_t>::max()
                                        : static_cast<std::uint64_t>(std::ldexp(p.queue_share, 64));
  CallScript out;
  for (std::uint32_t phase : phases) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed & 0xffffffffu),
                      static_cast<std::uint32_t>(seed >> 32), phase};
    std::mt19937_64 engine(seq);
    std::int64_t t = p.calls_from / step;  // in steps
    while (true) {
      do ++t;
      while (engine() >= arrives_below);
      if (t >= end) break;
      const bool queue = p.queue_share >= 1.0 || engine() < queue_below;
      const std::int64_t on =
          queue
              ? queue_min +
                    static_cast<std::int64_t>(Below(engine, static_cast<std::uint64_t>(queue_span)))
              : pass_min +
                    static_cast<std::int64_t>(Below(engine, static_cast<std::uint64_t>(pass_span)));
      const std::int64_t off = std::min(t + on, end);
      out.calls.push_back({phase, t * step, off * step});
      t = off;
    }
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
