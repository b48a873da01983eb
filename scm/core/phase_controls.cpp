#include "scm/core/phase_controls.h"

#include <algorithm>
#include <utility>

namespace autodrive::scm {

namespace {

constexpr std::pair<PhaseControlKind, std::string_view> kNames[] = {
    {PhaseControlKind::kOmit, "omit"}, {PhaseControlKind::kPedOmit, "ped_omit"},
    {PhaseControlKind::kHold, "hold"}, {PhaseControlKind::kForceOff, "force_off"},
    {PhaseControlKind::kCall, "call"}, {PhaseControlKind::kPedCall, "ped_call"}};

bool Same(const PhaseControl& c, PhaseControlKind kind, std::size_t plan, std::size_t phase) {
  return c.kind == kind && c.plan == plan && c.phase == phase;
}

}  // namespace

std::string_view ToString(PhaseControlKind kind) {
  for (const auto& [k, name] : kNames) {
    if (k == kind) return name;
  }
  return "?";
}

std::optional<PhaseControlKind> PhaseControlFromString(std::string_view name) {
  for (const auto& [k, n] : kNames) {
    if (n == name) return k;
    // The command line's spelling: force-off, ped-call.
    if (n.size() == name.size() && std::ranges::equal(n, name, [](char a, char b) {
          return a == b || (a == '_' && b == '-');
        }))
      return k;
  }
  return std::nullopt;
}

std::string_view PhaseControlNames() { return "omit, ped_omit, hold, force_off, call, ped_call"; }

bool PhaseControls::Set(const PhaseControl& control) {
  for (auto& c : controls_) {
    if (Same(c, control.kind, control.plan, control.phase)) {
      c = control;
      return true;
    }
  }
  controls_.push_back(control);
  return false;
}

bool PhaseControls::Clear(PhaseControlKind kind, std::size_t plan, std::size_t phase) {
  return std::erase_if(controls_,
                       [&](const PhaseControl& c) { return Same(c, kind, plan, phase); }) > 0;
}

bool PhaseControls::Active(PhaseControlKind kind, std::size_t plan, std::size_t phase) const {
  return std::ranges::any_of(controls_,
                             [&](const PhaseControl& c) { return Same(c, kind, plan, phase); });
}

std::size_t PhaseControls::Count(PhaseControlKind kind, std::size_t plan) const {
  return static_cast<std::size_t>(std::ranges::count_if(
      controls_, [&](const PhaseControl& c) { return c.kind == kind && c.plan == plan; }));
}

std::vector<PhaseControl> PhaseControls::Expire(MonoTime now) {
  std::vector<PhaseControl> out;
  if (controls_.empty()) return out;
  std::erase_if(controls_, [&](const PhaseControl& c) {
    if (c.once || now < c.until) return false;
    out.push_back(c);
    return true;
  });
  return out;
}

std::vector<PhaseControl> PhaseControls::EndOnce() {
  std::vector<PhaseControl> out;
  std::erase_if(controls_, [&](const PhaseControl& c) {
    if (!c.once) return false;
    out.push_back(c);
    return true;
  });
  return out;
}

MonoTime PhaseControls::next_expiry() const {
  MonoTime t = MonoTime::max();
  for (const auto& c : controls_) {
    if (!c.once) t = std::min(t, c.until);
  }
  return t;
}

}  // namespace autodrive::scm
