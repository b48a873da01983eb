#include "scm/core/ring_plan.h"

#include <fmt/format.h>

#include <algorithm>

namespace autodrive::scm {

std::string_view ToString(Recall recall) {
  switch (recall) {
    case Recall::kNone:
      return "none";
    case Recall::kMin:
      return "min";
    case Recall::kMax:
      return "max";
    case Recall::kPed:
      return "ped";
    case Recall::kSoft:
      return "soft";
  }
  return "?";
}

const RingPhase* RingPlan::Find(std::uint32_t number) const {
  const auto it = std::ranges::find(phases, number, &RingPhase::number);
  return it == phases.end() ? nullptr : &*it;
}

RingPlan RingPlanOf(const IntersectionModel& x, const Plan& plan) {
  RingPlan out;
  if (plan.type != PlanType::kFixed && plan.type != PlanType::kActuated) return out;
  const bool fixed = plan.type == PlanType::kFixed;
  std::vector<bool> detected(x.groups.size(), false);
  for (const Detector& d : plan.detectors) detected[d.group] = true;
  out.rings.emplace_back();
  for (std::size_t k = 0; k < plan.phases.size(); ++k) {
    const Phase& stage = plan.phases[k];
    const auto& next = plan.phases[(k + 1) % plan.phases.size()].groups;
    RingPhase p;
    p.number = static_cast<std::uint32_t>(k + 1);
    p.groups = stage.groups;
    p.max1 = p.max2 = stage.green;
    p.passage = fixed ? Duration{0} : plan.extension;
    bool always_called = false;
    for (std::size_t g : stage.groups) {
      const GroupTiming& t = x.groups[g].timing;
      p.min_green = std::max(p.min_green, t.min_green);
      if (std::ranges::find(next, g) == next.end()) {
        p.yellow = std::max(p.yellow, t.yellow);
        p.red_clear = std::max(p.red_clear, t.red_clearance);
      }
      if (!detected[g]) always_called = true;
    }
    p.recall = fixed ? Recall::kMax : (always_called ? Recall::kMin : Recall::kNone);
    p.non_lock = true;
    out.rings[0].push_back(p.number);
    if (fixed) out.cycle += p.max1 + p.yellow + p.red_clear;
    out.phases.push_back(std::move(p));
  }
  out.offset = plan.offset;
  return out;
}

std::string DescribeRingPlan(const IntersectionModel& x, const RingPlan& plan) {
  if (plan.phases.empty()) return "  no phases (flash or dark)\n";
  const auto s = [](Duration d) { return fmt::format("{:.1f}", ToSeconds(d)); };
  std::string out =
      fmt::format("  {:>5} {:>4} {:>9} {:>7} {:>6} {:>6} {:>6} {:>9} {:>6} {:>8}  {}\n", "phase",
                  "ring", "min_green", "passage", "max1", "max2", "yellow", "red_clear", "recall",
                  "non_lock", "groups");
  for (const RingPhase& p : plan.phases) {
    std::string groups;
    for (std::size_t g : p.groups) {
      if (!groups.empty()) groups += ", ";
      groups += fmt::format("{} ({})", x.groups[g].id.value(), x.groups[g].name);
    }
    out +=
        fmt::format("  {:>5} {:>4} {:>9} {:>7} {:>6} {:>6} {:>6} {:>9} {:>6} {:>8}  {}\n", p.number,
                    p.ring, s(p.min_green), s(p.passage), s(p.max1), s(p.max2), s(p.yellow),
                    s(p.red_clear), ToString(p.recall), p.non_lock ? "yes" : "no", groups);
  }
  for (std::size_t r = 0; r < plan.rings.size(); ++r) {
    out += fmt::format("  ring {} sequence: {}\n", r + 1, fmt::join(plan.rings[r], ", "));
  }
  if (plan.cycle > Duration::zero()) {
    out += fmt::format("  cycle {} s, offset {} s (from local midnight)\n", s(plan.cycle),
                       s(plan.offset));
  }
  return out;
}

}  // namespace autodrive::scm
