#include "infrastructure/conflict_monitor.h"

#include <algorithm>
#include <cstdio>

#include "common/error.h"

namespace autodrive::infrastructure {
namespace {

const maps::Intersection& FindIntersection(const maps::Map& map, IntersectionId id) {
  for (const auto& x : map.intersections) {
    if (x.id == id) return x;
  }
  throw InputError("map " + map.name + " has no intersection " + std::to_string(id.value()));
}

const maps::SignalHead& FindHead(const maps::Map& map, SignalHeadId id) {
  for (const auto& h : map.signal_heads) {
    if (h.id == id) return h;
  }
  throw InputError("map " + map.name + " has no signal head " + std::to_string(id.value()));
}

// "green", "yellow", "green and yellow": the go lamps lit.
std::string GoLamps(const Lamps& lamps) {
  if (lamps.green && lamps.yellow) return "green and yellow";
  if (lamps.green) return "green";
  if (lamps.yellow) return "yellow";
  return "no go lamp";
}

bool ShowsGo(const Lamps& lamps) { return lamps.green || lamps.yellow; }

}  // namespace

std::vector<HeadConflict> ComputeHeadConflicts(const maps::Map& map, IntersectionId intersection) {
  const maps::Intersection& x = FindIntersection(map, intersection);
  std::vector<SignalHeadId> heads = x.signal_heads;
  std::sort(heads.begin(), heads.end());
  const auto movements_from = [&](SignalHeadId head) {
    const ApproachId approach = FindHead(map, head).approach;
    std::vector<MovementId> out;
    for (const MovementId m : x.movements) {
      if (map.movement(m).from_approach == approach) out.push_back(m);
    }
    return out;
  };
  std::vector<HeadConflict> conflicts;
  for (std::size_t i = 0; i < heads.size(); ++i) {
    const auto from_a = movements_from(heads[i]);
    for (std::size_t j = i + 1; j < heads.size(); ++j) {
      const auto from_b = movements_from(heads[j]);
      HeadConflict c{heads[i], heads[j], {}};
      for (const MovementId ma : from_a) {
        for (const MovementId mb : from_b) {
          if (ma != mb && map.Conflict(ma, mb)) c.movements.emplace_back(ma, mb);
        }
      }
      std::sort(c.movements.begin(), c.movements.end());
      if (!c.movements.empty()) conflicts.push_back(std::move(c));
    }
  }
  return conflicts;
}

ConflictMonitor::ConflictMonitor(const maps::Map& map, IntersectionId intersection,
                                 const std::vector<SignalHeadId>& hosted, Duration persistence)
    : intersection_(intersection), persistence_(persistence) {
  AUTODRIVE_CHECK(persistence > Duration::zero());
  const maps::Intersection& x = FindIntersection(map, intersection);
  name_ = x.name;
  heads_ = hosted.empty() ? x.signal_heads : hosted;
  std::sort(heads_.begin(), heads_.end());
  for (const SignalHeadId h : heads_) {
    AUTODRIVE_THROW_UNLESS(
        std::find(x.signal_heads.begin(), x.signal_heads.end(), h) != x.signal_heads.end(),
        "signal head " << h.value() << " is not a head of intersection " << x.name);
  }
  for (auto& c : ComputeHeadConflicts(map, intersection)) {
    const auto hosted_head = [&](SignalHeadId h) {
      return std::find(heads_.begin(), heads_.end(), h) != heads_.end();
    };
    if (hosted_head(c.a) && hosted_head(c.b)) conflicts_.push_back(std::move(c));
  }
  for (const auto& m : map.movements) movement_names_.push_back(m.name);
  states_.resize(heads_.size());
}

ConflictMonitor::HeadState* ConflictMonitor::Find(SignalHeadId head) {
  const auto it = std::find(heads_.begin(), heads_.end(), head);
  return it == heads_.end() ? nullptr : &states_[static_cast<std::size_t>(it - heads_.begin())];
}

void ConflictMonitor::Observe(SignalHeadId head, const std::optional<Lamps>& lamps, MonoTime now) {
  HeadState* state = Find(head);
  if (state == nullptr) return;
  state->lamps = lamps;
  if (lamps && ShowsGo(*lamps)) {
    if (!state->go_since) state->go_since = now;
  } else {
    state->go_since.reset();
  }
}

std::optional<MonitorLatch> ConflictMonitor::Update(MonoTime now) {
  if (latch_) return std::nullopt;
  for (const auto& c : conflicts_) {
    const HeadState& a = *Find(c.a);
    const HeadState& b = *Find(c.b);
    if (!a.go_since || !b.go_since) continue;
    const MonoTime since = std::max(*a.go_since, *b.go_since);
    if (now - since < persistence_) continue;
    MonitorLatch latch;
    latch.a = c.a;
    latch.b = c.b;
    latch.lamps_a = *a.lamps;
    latch.lamps_b = *b.lamps;
    latch.since = since;
    latch.at = now;
    const auto& [ma, mb] = c.movements.front();
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.2f s", ToSeconds(now - since));
    latch.message = SignalHeadName(c.a) + " showed " + GoLamps(latch.lamps_a) + " and " +
                    SignalHeadName(c.b) + " showed " + GoLamps(latch.lamps_b) + " together for " +
                    seconds + "; their movements conflict (" + movement_names_[ma.value() - 1] +
                    " with " + movement_names_[mb.value() - 1] + ")";
    latch_ = latch;
    return latch;
  }
  return std::nullopt;
}

void ConflictMonitor::RestartTimers() {
  for (HeadState& state : states_) state.go_since.reset();
}

std::optional<MonoTime> ConflictMonitor::NextLatch() const {
  if (latch_) return std::nullopt;
  std::optional<MonoTime> next;
  const auto state_of = [&](SignalHeadId head) -> const HeadState& {
    return states_[static_cast<std::size_t>(std::find(heads_.begin(), heads_.end(), head) -
                                            heads_.begin())];
  };
  for (const auto& c : conflicts_) {
    const HeadState& a = state_of(c.a);
    const HeadState& b = state_of(c.b);
    if (!a.go_since || !b.go_since) continue;
    const MonoTime at = std::max(*a.go_since, *b.go_since) + persistence_;
    if (!next || at < *next) next = at;
  }
  return next;
}

bool ConflictMonitor::Reset() {
  const bool was = latch_.has_value();
  latch_.reset();
  return was;
}

}  // namespace autodrive::infrastructure
