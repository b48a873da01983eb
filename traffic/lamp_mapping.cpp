#include "traffic/lamp_mapping.h"

#include <algorithm>

namespace autodrive::traffic {

LampMapping::LampMapping(const LightBinding& lights, std::size_t heads, Duration flash_window,
                         Duration step)
    : lights_(&lights), flash_window_(flash_window), step_(step) {
  const std::size_t n = lights.lights().size();
  heads_.resize(heads + 1);
  states_.resize(n);
  aspects_.resize(n);
  held_.resize(n);
  for (std::size_t i = 0; i < n; ++i) held_[i].assign(lights.lights()[i].heads.size(), false);
  recheck_until_.assign(n, MonoTime{});
  relight_.assign(n, false);
  lights_of_head_.resize(heads_.size());
  for (std::size_t i = 0; i < n; ++i) {
    for (const auto& link : lights.lights()[i].heads) {
      for (const SignalHeadId h : link) {
        auto& of = lights_of_head_.at(h.value());
        if (std::find(of.begin(), of.end(), i) == of.end()) of.push_back(i);
      }
    }
  }
}

void LampMapping::Report(SignalHeadId head, int lamp, MonoTime now) {
  if (head.value() >= heads_.size()) return;
  HeadReading& reading = heads_[head.value()];
  if (!reading.Report(lamp, now)) return;
  // The lights it shows are read again at the next step, and, where a flash may be starting or
  // ending, until a flash window after the change.
  for (const std::size_t light : lights_of_head_[head.value()]) {
    relight_[light] = true;
    if (reading.MayFlash()) {
      recheck_until_[light] = std::max(recheck_until_[light], now + flash_window_ + step_);
    }
  }
}

void LampMapping::Hold(const std::vector<MovementId>& held, const LinkIndex& links) {
  std::vector<std::vector<bool>> before;
  for (const std::size_t i : held_lights_) {
    before.push_back(held_[i]);
    std::fill(held_[i].begin(), held_[i].end(), false);
  }
  std::vector<std::size_t> lights;
  for (const MovementId m : held) {
    if (m.value() >= links.link_of_movement.size()) continue;
    const auto [light, link] = links.link_of_movement[m.value()];
    if (light == LinkIndex::kNoLight) continue;
    held_[light][link] = true;
    if (std::find(lights.begin(), lights.end(), light) == lights.end()) lights.push_back(light);
  }
  // A light whose held links changed is set again at once.
  for (std::size_t j = 0; j < held_lights_.size(); ++j) {
    if (held_[held_lights_[j]] != before[j]) relight_[held_lights_[j]] = true;
  }
  for (const std::size_t i : lights) {
    if (std::find(held_lights_.begin(), held_lights_.end(), i) == held_lights_.end()) {
      relight_[i] = true;
    }
  }
  held_lights_ = std::move(lights);
}

const std::vector<std::size_t>& LampMapping::Update(MonoTime now, AllWayStops& stops) {
  changed_.clear();
  for (std::size_t i = 0; i < states_.size(); ++i) {
    // Only where a lamp changed lately, or an all-way stop is being run.
    if (!stops.running(i) && !relight_[i] && now > recheck_until_[i] && !states_[i].empty()) {
      continue;
    }
    relight_[i] = false;
    aspects_[i] = lights_->State(i, heads_, now, flash_window_);
    stops.SetRunning(i, aspects_[i].find('s') != std::string::npos);
    // All-way stop links: red, but green for the vehicles let through.
    std::string state = aspects_[i];
    for (char& c : state) {
      if (c == 's') c = 'r';
    }
    for (const AllWayStops::Grant& g : stops.grants(i)) {
      if (aspects_[i][g.link] == 's') state[g.link] = 'G';
    }
    for (std::size_t k = 0; k < state.size(); ++k) {
      if (held_[i][k]) state[k] = 'r';
    }
    if (state == states_[i]) continue;
    states_[i] = std::move(state);
    changed_.push_back(i);
  }
  return changed_;
}

}  // namespace autodrive::traffic
