#include "vehicle_sim/internal/background_traffic.h"

#include <spdlog/spdlog.h>

#include <utility>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::vehicle_sim::internal {

BackgroundTraffic::BackgroundTraffic(const dds::Participant& participant, bool read,
                                     std::vector<std::string> car_names, bool looks)
    : car_names_(std::move(car_names)), want_looks_(looks) {
  if (read) {
    reader_ =
        std::make_unique<dds::Reader<msg::TrafficObjects>>(participant, dds::topics::Traffic());
  }
}

bool BackgroundTraffic::TakeNewest(Time now) {
  bool fresh = false;
  while (reader_->TakeOne(incoming_)) {
    std::swap(newest_, incoming_);
    fresh = true;
  }
  if (!fresh) return false;
  ++messages_;
  const TrafficReadReport report = ReadTrafficObjects(*newest_, objects_);
  std::string problem = report.first_problem;
  try {
    stamp_ = dds::FromMsg(newest_->header.stamp);
  } catch (const InputError& e) {
    stamp_ = now;  // taken as it is
    if (problem.empty()) problem = std::string("its stamp: ") + e.what();
  }
  if (!problem.empty() && ++bad_messages_ % 100 == 1) {
    spdlog::warn("background traffic: message {} ({} bad so far): {} object(s) left out; {}",
                 messages_, bad_messages_, report.skipped, problem);
  }
  if (messages_ == 1) {
    spdlog::info("background traffic: {} object(s) in the first message", objects_.size());
  }
  return true;
}

void BackgroundTraffic::Take(Time now, bool extrapolate, World& world) {
  if (!reader_) return;
  const bool fresh = TakeNewest(now);
  const Duration after = extrapolate ? TrafficExtrapolation(stamp_, now) : Duration{0};
  if (!fresh && placed_after_ == after) return;
  placed_after_ = after;
  const auto first_id = static_cast<std::uint32_t>(car_names_.size());
  boxes_.clear();
  looks_.clear();
  for (std::size_t k = 0; k < objects_.size(); ++k) {
    const Eigen::Isometry3d X_MO = TrafficPoseAfter(objects_[k], after);
    boxes_.push_back(
        TrafficBox(objects_[k], X_MO, BoxId(first_id + static_cast<std::uint32_t>(k))));
    if (want_looks_) looks_.push_back(TrafficLook(objects_[k], X_MO));
  }
  world.SetTraffic(boxes_);
}

void BackgroundTraffic::NoteContacts(const World& world) {
  const Duration now = world.time();
  for (const TrafficContact& c : world.TrafficContacts()) {
    const TrafficObject& object = objects_.at(static_cast<std::size_t>(c.traffic));
    if (!touches_.Touch(c.vehicle, object.id, now)) continue;
    collisions_.fetch_add(1);
    const Eigen::Vector3d car = world.State(c.vehicle).X_MV.translation();
    const Eigen::Vector3d box = object.X_MO.translation();
    spdlog::warn(
        "{} (at {:.3f}, {:.3f}) ran into background {} '{}' (at {:.3f}, {:.3f}) at t = {:.3f} s",
        car_names_.at(static_cast<std::size_t>(c.vehicle)), car.x(), car.y(),
        ToString(object.object_class), object.id, box.x(), box.y(), ToSeconds(now));
  }
  touches_.Forget(now);
}

}  // namespace autodrive::vehicle_sim::internal
