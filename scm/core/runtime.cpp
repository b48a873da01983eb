#include "scm/core/runtime.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/error.h"

namespace autodrive::scm {

CityRuntime::CityRuntime(std::unique_ptr<const City> city) : city_(std::move(city)) {
  AUTODRIVE_CHECK(city_ != nullptr);
  xs_.reserve(city_->intersections.size());
  for (const auto& model : city_->intersections) {
    IntersectionRuntime x;
    x.model = &model;
    const std::size_t n = model.groups.size();
    x.calls.assign(n, false);
    x.last_calls.assign(n, false);
    for (std::size_t g = 0; g < n; ++g) {
      for (SignalHeadId h : model.groups[g].heads) {
        head_index_[h] = heads_.size();
        x.heads.push_back(heads_.size());
        heads_.push_back(HeadSlot{h, xs_.size(), g, SignalHeadName(h)});
      }
    }
    xs_.push_back(std::move(x));
  }
}

void CityRuntime::Start(MonoTime now, const std::vector<IntersectionStateRecord>& restore) {
  for (auto& x : xs_) {
    const IntersectionModel& model = *x.model;
    Mode mode = Mode::kAuto;
    std::optional<std::size_t> plan;
    for (const auto& saved : restore) {
      if (saved.intersection != model.id) continue;
      mode = ModeFromString(saved.mode).value_or(Mode::kAuto);
      if (saved.operator_chosen) plan = model.PlanIndex(saved.plan);
      spdlog::info("{}: restoring mode {} and plan {}", model.name, ToString(mode),
                   plan ? model.plans[*plan].name : std::string("(schedule)"));
    }
    x.controller.emplace(model, now, mode, plan);
    x.monitor.emplace(model, now);
    x.last_aspects = x.controller->aspects();
    x.saved_mode = std::string(ToString(mode));
    x.saved_plan = plan ? model.plans[*plan].name : "auto";
    x.last_minute = -1;
    x.fault.clear();
    std::fill(x.last_calls.begin(), x.last_calls.end(), false);
  }
}

void CityRuntime::Start(const ClockReading& now,
                        const std::vector<IntersectionStateRecord>& restore) {
  Start(now.mono, restore);
  for (const IntersectionStateRecord& saved : restore) {
    const auto xi = Find(saved.intersection);
    if (!xi) continue;
    IntersectionRuntime& x = xs_[*xi];
    for (const PhaseControlRecord& r : saved.controls) {
      const auto kind = PhaseControlFromString(r.control);
      const auto plan = x.model->PlanIndex(r.plan);
      const bool put_back =
          kind && plan && r.phase >= 1 &&
          x.controller->RestoreControl(
              {*kind, *plan, r.phase - 1, now.mono + (r.until - now.wire), false}, now.mono);
      if (put_back) {
        spdlog::info("{}: restoring {} of phase {} of plan {} for {:.1f} s", x.model->name,
                     r.control, r.phase, r.plan, ToSeconds(r.until - now.wire));
      } else if (r.until > now.wire) {
        spdlog::warn("{}: the saved {} of phase {} of plan {} no longer fits the city: dropped",
                     x.model->name, r.control, r.phase, r.plan);
      }
    }
    x.saved_controls = x.controller->controls().all();
  }
}

std::optional<std::size_t> CityRuntime::HeadIndex(SignalHeadId id) const {
  const auto it = head_index_.find(id);
  if (it == head_index_.end()) return std::nullopt;
  return it->second;
}

std::optional<std::size_t> CityRuntime::Find(std::string_view name) const {
  for (std::size_t i = 0; i < xs_.size(); ++i) {
    const auto& m = *xs_[i].model;
    if (m.name == name || std::to_string(m.id.value()) == name) return i;
  }
  return std::nullopt;
}

std::optional<std::size_t> CityRuntime::Find(IntersectionId id) const {
  for (std::size_t i = 0; i < xs_.size(); ++i) {
    if (xs_[i].model->id == id) return i;
  }
  return std::nullopt;
}

Aspect CityRuntime::AspectOfHead(std::size_t h) const {
  const HeadSlot& head = heads_[h];
  return xs_[head.intersection].last_aspects[head.group];
}

MonoTime CityRuntime::next_wake() const {
  MonoTime next = MonoTime::max();
  for (const auto& x : xs_) next = std::min(next, x.controller->next_wake());
  return next;
}

StepReport CityRuntime::Step(const ClockReading& now, const DayClock& day,
                             const FleetRegistry* fleet, EventSink& events) {
  StepReport report;
  for (std::size_t i = 0; i < xs_.size(); ++i) {
    IntersectionRuntime& x = xs_[i];
    IntersectionController& c = *x.controller;
    // Detector calls of the running plan (groups without a detector are on recall in the
    // controller). Only plans with detectors ask the fleet.
    std::fill(x.calls.begin(), x.calls.end(), false);
    if (fleet != nullptr) {
      for (const auto& d : c.plan().detectors) {
        if (!x.calls[d.group] &&
            fleet->Occupied({d.lane, d.from_stop_line_m, d.to_stop_line_m}, now.wire)) {
          x.calls[d.group] = true;
        }
      }
    }
    const bool inputs_changed = x.calls != x.last_calls || day.minute_of_day != x.last_minute;
    if (!inputs_changed && now.mono < c.next_wake()) continue;
    for (std::size_t g = 0; g < x.calls.size(); ++g) {
      if (x.calls[g] != x.last_calls[g]) c.LogDetector(now.mono, g, x.calls[g]);
    }
    x.last_calls = x.calls;
    x.last_minute = day.minute_of_day;
    StepOne(i, now, day, events, &report);
  }
  return report;
}

void CityRuntime::StepOne(std::size_t i, const ClockReading& now, const DayClock& day,
                          EventSink& events, StepReport* report) {
  StepReport local;
  StepReport& r = report != nullptr ? *report : local;
  IntersectionRuntime& x = xs_[i];
  x.controller->Step(now.mono, x.calls, day);
  ++r.stepped;
  Check(i, now.mono, events, r);
}

void CityRuntime::Check(std::size_t i, MonoTime now, EventSink& events, StepReport& report) {
  IntersectionRuntime& x = xs_[i];
  IntersectionController& c = *x.controller;
  const bool was_latched = c.latched();
  const std::vector<Aspect>& aspects = c.aspects();
  if (aspects == x.last_aspects) return;  // nothing new to check or send
  if (const auto v = x.monitor->Check(now, aspects)) {
    ++report.monitor_violations;
    c.FailSafe(now, "conflict monitor: " + v->message);
    events.Emit(
        Event{Severity::kCritical, "monitor_" + v->rule, v->message, x.model->id, "", "scm", true});
  }
  x.monitor->Record(now, c.aspects());
  if (c.latched() && !was_latched) {
    spdlog::error("{}: fail-safe flash latched: {}", x.model->name, c.latch_reason());
  }
  if (c.aspects() != x.last_aspects) {
    ++x.revision;
    x.last_aspects = c.aspects();
    ++report.changed;
  }
}

bool CityRuntime::FailSafe(std::size_t i, MonoTime now, const std::string& reason,
                           EventSink& events) {
  IntersectionRuntime& x = xs_[i];
  if (x.controller->latched()) return false;
  x.fault = reason;
  x.controller->FailSafe(now, reason);
  StepReport report;
  Check(i, now, events, report);  // the flash is the output from now on, for the monitor too
  return true;
}

IntersectionSummary CityRuntime::Summary(std::size_t i) const {
  const IntersectionRuntime& x = xs_[i];
  const auto& c = *x.controller;
  const std::optional<std::size_t> asked = c.operator_plan();
  const bool running_asked = asked && *asked == c.plan_index();
  return {x.model->id,
          c.effective_mode(),
          c.requested_mode(),
          c.plan().name,
          running_asked,
          c.stage(),
          c.latched() ? std::optional<std::string>(c.latch_reason()) : std::nullopt,
          asked && !running_asked ? std::optional<std::string>(x.model->plans[*asked].name)
                                  : std::nullopt};
}

std::string CityRuntime::Describe(std::size_t i) const { return scm::Describe(Summary(i)); }

std::string Describe(const IntersectionSummary& s) {
  return fmt::format(
      "id={} mode={} requested={} plan={}{} stage={}{}{}", s.id.value(), ToString(s.mode),
      ToString(s.requested), s.plan, s.plan_by_operator ? " (operator)" : " (schedule)",
      ToString(s.stage),
      s.pending_plan ? " next plan=" + *s.pending_plan + " (operator, at the next safe point)" : "",
      s.latched ? " latched=\"" + *s.latched + "\"" : "");
}

std::vector<IntersectionStateRecord> CityRuntime::OperatorStates(Time now) const {
  std::vector<IntersectionStateRecord> out;
  for (const auto& x : xs_) {
    const auto& c = *x.controller;
    out.push_back({x.model->id,
                   std::string(ToString(c.requested_mode())),
                   c.operator_plan() ? x.model->plans[*c.operator_plan()].name : "auto",
                   c.operator_plan().has_value(),
                   now,
                   {}});
  }
  return out;
}

std::optional<IntersectionStateRecord> CityRuntime::TakeStateToSave(std::size_t i,
                                                                    const ClockReading& now) {
  IntersectionRuntime& x = xs_[i];
  const auto& c = *x.controller;
  const std::string mode(ToString(c.requested_mode()));
  const std::string plan = c.operator_plan() ? x.model->plans[*c.operator_plan()].name : "auto";
  std::vector<PhaseControl> controls;
  for (const PhaseControl& pc : c.controls().all()) {
    if (!pc.once) controls.push_back(pc);  // an advance lasts one green: not worth a restart
  }
  if (mode == x.saved_mode && plan == x.saved_plan && controls == x.saved_controls) {
    return std::nullopt;
  }
  x.saved_mode = mode;
  x.saved_plan = plan;
  x.saved_controls = controls;
  IntersectionStateRecord out{x.model->id, mode, plan, true, now.wire, {}};
  for (const PhaseControl& pc : controls) {
    out.controls.push_back({std::string(ToString(pc.kind)), x.model->plans[pc.plan].name,
                            static_cast<std::uint32_t>(pc.phase + 1), now.ToWire(pc.until)});
  }
  return out;
}

}  // namespace autodrive::scm
