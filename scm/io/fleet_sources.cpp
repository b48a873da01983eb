#include "scm/io/fleet_sources.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "common/dds/conversions.h"
#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::scm {

IpsSource::IpsSource(const dds::Participant& participant, const std::vector<VehicleId>& vehicles,
                     ClockKind clock)
    : clock_(clock) {
  for (const VehicleId v : vehicles) {
    Track t;
    t.vehicle = v;
    t.reader = std::make_unique<dds::Reader<msg::Point>>(participant, dds::topics::Ips(v));
    tracks_.push_back(std::move(t));
  }
}

std::size_t IpsSource::Poll(const ClockReading& now, FleetRegistry& fleet) {
  std::size_t recorded = 0;
  for (Track& t : tracks_) {
    while (t.reader->TakeOne(sample_, &info_)) {
      const msg::Point& p = *sample_;
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
        ++malformed_;
        continue;
      }
      const Eigen::Vector2d pos(p.x, p.y);
      if (t.last && (pos - *t.last).norm() > kMinMotion_m) {
        t.yaw_rad = std::atan2(pos.y() - t.last->y(), pos.x() - t.last->x());
      }
      if (!t.last || (pos - *t.last).norm() > kMinMotion_m) t.last = pos;
      VehicleObservation o;
      o.vehicle = t.vehicle;
      o.source = PoseSource::kIps;
      o.observed = now.wire;
      if (clock_ == ClockKind::kWall) {
        const Time written{std::chrono::duration_cast<Time::duration>(
            std::chrono::nanoseconds(info_.source_timestamp_ns))};
        if (written <= now.wire && now.wire - written <= kMaxWriterAge) o.observed = written;
      }
      o.heading_known = t.yaw_rad.has_value();
      o.X_MV = RigidTransform2(pos, t.yaw_rad.value_or(0.0)).ToRigidTransform3();
      try {
        if (fleet.Observe(o)) ++recorded;
      } catch (const InputError& e) {
        ++malformed_;
        spdlog::warn("bad observation of {}: {}", VehicleName(t.vehicle), e.what());
      }
    }
  }
  return recorded;
}

EyeSource::EyeSource(const dds::Participant& participant)
    : reader_(participant, dds::topics::EyeFleet()) {}

std::size_t EyeSource::Poll(const ClockReading& /*now*/, FleetRegistry& fleet) {
  std::size_t recorded = 0;
  while (reader_.TakeOne(sample_)) {
    for (const auto& v : dds::Elements(sample_->vehicles)) {
      VehicleObservation o;
      try {
        o.vehicle = ParseVehicleName(dds::View(v.vehicle_id));
        o.source = PoseSource::kEye;
        o.observed = dds::FromMsg(v.observed);
        o.X_MV = dds::FromMsg(v.pose.pose);
        o.speed_mps = v.twist.twist.linear.x;
        std::copy(std::begin(v.pose.covariance), std::end(v.pose.covariance),
                  o.pose_covariance.begin());
        o.tag = TagId(v.tag_id);
        o.heading_known = true;
        if (!std::isfinite(o.speed_mps)) throw InputError("speed is not finite");
        if (fleet.Observe(o)) ++recorded;
      } catch (const InputError& e) {
        if (malformed_++ % 100 == 0) spdlog::warn("bad Eye observation: {}", e.what());
      }
    }
  }
  return recorded;
}

TrafficSource::TrafficSource(const dds::Participant& participant)
    : reader_(participant, dds::topics::Traffic()) {}

std::size_t TrafficSource::Poll(const ClockReading& /*now*/, FleetRegistry& fleet) {
  std::size_t recorded = 0;
  while (reader_.TakeOne(sample_)) {
    const auto objects = dds::Elements(sample_->objects);
    batch_.clear();
    batch_.reserve(objects.size());
    for (const auto& o : objects) {
      batch_.push_back(TrafficObservation{dds::View(o.object_id), dds::View(o.map_lane_id),
                                          Eigen::Vector2d(o.pose.position.x, o.pose.position.y),
                                          o.size.x});
    }
    const TrafficUpdate u = fleet.ObserveTraffic(dds::FromMsg(sample_->header.stamp), batch_);
    recorded += u.recorded;
    if (u.refused > 0) {
      if (malformed_ == 0 || malformed_ / 1000 != (malformed_ + u.refused) / 1000) {
        spdlog::warn(
            "traffic: {} of {} objects refused (an empty or overlong id, a position or "
            "length that is not finite, or more than {} vehicles)",
            u.refused, objects.size(), FleetRegistry::kMaxTrafficVehicles);
      }
      malformed_ += u.refused;
    }
  }
  return recorded;
}

}  // namespace autodrive::scm
