#include "scm/core/conflict_monitor.h"

#include <fmt/format.h>

#include "common/error.h"

namespace autodrive::scm {

namespace {
std::string Label(const IntersectionModel& m, std::size_t g) {
  return fmt::format("group {} ({})", m.groups[g].id.value(), m.groups[g].name);
}
std::string Secs(Duration d) { return fmt::format("{:.3f} s", ToSeconds(d)); }
}  // namespace

ConflictMonitor::ConflictMonitor(const IntersectionModel& model, MonoTime now)
    : model_(&model),
      aspects_(model.groups.size()),
      since_(model.groups.size(), now),
      red_since_(model.groups.size()),
      green_end_(model.groups.size()) {
  for (std::size_t g = 0; g < aspects_.size(); ++g) aspects_[g] = model.groups[g].flash_aspect;
}

std::optional<Violation> ConflictMonitor::Check(MonoTime now,
                                                const std::vector<Aspect>& next) const {
  const auto& m = *model_;
  AUTODRIVE_CHECK(next.size() == aspects_.size(),
                  "monitor of " << m.name << " got " << next.size() << " aspects");
  const std::size_t n = next.size();
  auto fail = [&](std::string rule, std::string message) {
    return Violation{std::move(rule), fmt::format("{}: {}", m.name, message)};
  };
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      if (m.conflicts[a][b] && IsGo(next[a]) && IsGo(next[b])) {
        return fail("conflict",
                    fmt::format("{} {} and {} {} conflict; rule: conflicting groups "
                                "are never green or yellow together",
                                Label(m, a), ToString(next[a]), Label(m, b), ToString(next[b])));
      }
    }
  }
  for (std::size_t g = 0; g < n; ++g) {
    const Aspect was = aspects_[g];
    const Aspect now_shows = next[g];
    if (was == now_shows) continue;
    const auto& timing = m.groups[g].timing;
    const Duration held = now - since_[g];
    const bool to_flash = IsFlashing(now_shows) || now_shows == Aspect::kOff;
    if (was == Aspect::kGreen && !to_flash) {
      if (now_shows != Aspect::kYellow) {
        return fail("green_not_to_yellow",
                    fmt::format("{} went from green to {}; rule: a green ends in yellow",
                                Label(m, g), ToString(now_shows)));
      }
      if (held < timing.min_green) {
        return fail("short_green", fmt::format("{} green lasted {} of its min green {}; rule: "
                                               "minimum green",
                                               Label(m, g), Secs(held), Secs(timing.min_green)));
      }
    }
    if (was == Aspect::kYellow && !to_flash) {
      if (now_shows != Aspect::kRed) {
        return fail("yellow_not_to_red",
                    fmt::format("{} went from yellow to {}; rule: a yellow ends in red",
                                Label(m, g), ToString(now_shows)));
      }
      if (held < timing.yellow) {
        return fail("short_yellow", fmt::format("{} yellow lasted {} of its minimum {}; rule: "
                                                "minimum yellow",
                                                Label(m, g), Secs(held), Secs(timing.yellow)));
      }
    }
    if (now_shows == Aspect::kYellow && was != Aspect::kGreen) {
      return fail("yellow_not_after_green",
                  fmt::format("{} went from {} to yellow; rule: a yellow follows a green",
                              Label(m, g), ToString(was)));
    }
    if (now_shows == Aspect::kGreen) {
      if (was != Aspect::kRed) {
        return fail("green_not_from_red",
                    fmt::format("{} went from {} to green; rule: a green starts from steady red "
                                "after all red",
                                Label(m, g), ToString(was)));
      }
      for (std::size_t h = 0; h < n; ++h) {
        if (!m.conflicts[g][h]) continue;
        const Duration clear = m.groups[h].timing.red_clearance;
        if (!red_since_[h] || next[h] != Aspect::kRed || now - *red_since_[h] < clear) {
          const std::string red_for = red_since_[h]
                                          ? fmt::format("red for {}", Secs(now - *red_since_[h]))
                                          : fmt::format("showing {}", ToString(aspects_[h]));
          return fail("short_all_red",
                      fmt::format("{} turned green while conflicting {} was {}, under its red "
                                  "clearance {}; rule: minimum all-red",
                                  Label(m, g), Label(m, h), red_for, Secs(clear)));
        }
        const Duration intergreen = m.intergreens.empty() ? Duration{0} : m.intergreens[h][g];
        if (green_end_[h] && now - *green_end_[h] < intergreen) {
          return fail(
              "short_intergreen",
              fmt::format("{} turned green {} after conflicting {}'s green ended, under "
                          "their intergreen {}; rule: intergreen matrix",
                          Label(m, g), Secs(now - *green_end_[h]), Label(m, h), Secs(intergreen)));
        }
      }
    }
  }
  return std::nullopt;
}

void ConflictMonitor::Record(MonoTime now, const std::vector<Aspect>& next) {
  AUTODRIVE_CHECK(next.size() == aspects_.size(), "monitor got the wrong number of aspects");
  for (std::size_t g = 0; g < next.size(); ++g) {
    if (aspects_[g] == next[g]) continue;
    if (aspects_[g] == Aspect::kGreen && next[g] == Aspect::kYellow) green_end_[g] = now;
    if (IsFlashing(next[g]) || next[g] == Aspect::kOff) green_end_[g].reset();
    aspects_[g] = next[g];
    since_[g] = now;
    red_since_[g] = next[g] == Aspect::kRed ? std::optional<MonoTime>(now) : std::nullopt;
  }
}

std::optional<Violation> ConflictMonitor::CheckAndRecord(MonoTime now,
                                                         const std::vector<Aspect>& next) {
  auto v = Check(now, next);
  if (!v) Record(now, next);
  return v;
}

}  // namespace autodrive::scm
