#include "traffic/service.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <map>
#include <optional>

#include "traffic/lamp_inbox.h"

#include "common/dds/conversions.h"
#include "common/dds/lockstep.h"
#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/ids.h"
#include "scm/core/city.h"

namespace autodrive::traffic {

namespace topics = dds::topics;

void FillTrafficObjects(const std::vector<TrafficVehicle>& vehicles, Time stamp,
                        std::vector<msg::TrafficObject>& buffer, msg::TrafficObjects& out) {
  buffer.resize(vehicles.size());
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    const TrafficVehicle& v = vehicles[i];
    msg::TrafficObject& o = buffer[i];
    o = msg::TrafficObject{};
    dds::BorrowString(o.object_id, v.id.c_str());
    o.object_class = v.object_class;
    o.pose.position.x = v.centre.x();
    o.pose.position.y = v.centre.y();
    o.pose.orientation.z = std::sin(v.yaw_rad / 2);
    o.pose.orientation.w = std::cos(v.yaw_rad / 2);
    o.size.x = v.length_m;
    o.size.y = v.width_m;
    o.size.z = v.height_m;
    o.speed_mps = v.speed_mps;
    dds::BorrowString(o.map_lane_id, v.map_lane.c_str());
    o.signals = v.signals;
  }
  out = msg::TrafficObjects{};
  out.header.stamp = dds::ToMsg(stamp);
  dds::BorrowString(out.header.frame_id, "map");
  dds::BorrowSequence(out.objects, std::span<msg::TrafficObject>(buffer));
}

const char* ObjectsCsvHeader() {
  return "stamp_s,id,class,x_m,y_m,yaw_rad,speed_mps,length_m,width_m,lane,signals";
}

namespace {

double YawOfQuaternion(double x, double y, double z, double w) {
  return std::atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z));
}

// The cars of the city's `sim` section, by name.
std::vector<std::string> SimVehicles(const scm::City& city) {
  std::vector<std::string> names;
  if (!city.config.sim) return names;
  const YAML::Node sim = YAML::Load(city.config.sim->yaml);
  if (sim["vehicles"]) {
    for (const auto& v : sim["vehicles"]) names.push_back(v["name"].as<std::string>());
  } else {
    names.emplace_back("nigel_1");  // the simulator's default car
  }
  return names;
}

// The lab cars expected: the ground truth's (the others are not known in advance).
CoSimulation::Options CosimOptions(const scm::City& city, const TrafficConfig& config,
                                   const TrafficServiceOptions& o) {
  CoSimulation::Options options{o.work_dir, nullptr, true, {}, std::chrono::seconds(5)};
  const bool truth = config.lab_cars.source == "ground_truth" ||
                     (config.lab_cars.source == "auto" && city.config.sim.has_value());
  if (truth) {
    options.expected_lab_cars =
        config.lab_cars.vehicles.empty() ? SimVehicles(city) : config.lab_cars.vehicles;
  }
  return options;
}

}  // namespace

struct TrafficService::Impl {
  const dds::Participant& participant;
  const scm::City& city;
  TrafficServiceOptions options;
  double step_s;
  CoSimulation cosim;
  std::string source;
  dds::Writer<msg::TrafficObjects> writer;
  // One inbox per domain the lamps are heard on: the service's, then each district's.
  std::vector<std::unique_ptr<LampInbox>> lamps;
  // Each district's own vehicles, on its domain (in the order of `city.districts.all()`).
  std::vector<std::unique_ptr<dds::Writer<msg::TrafficObjects>>> district_writers;
  std::vector<std::vector<TrafficVehicle>> district_vehicles;
  std::vector<LampInbox::Lamp> lamps_taken;
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> truth_readers;
  std::unique_ptr<dds::Reader<msg::FleetState>> fleet_reader;
  std::map<std::string, LabCarPose> cars;  // newest pose of each car
  std::vector<LabCarPose> fresh;           // cars heard since the last step
  std::vector<msg::TrafficObject> objects;
  dds::Message<msg::TrackedVehicle> truth_sample;
  dds::Message<msg::FleetState> fleet_sample;

  Impl(const dds::Participant& p, const scm::City& c, const TrafficConfig& config,
       TrafficServiceOptions o)
      : participant(p),
        city(c),
        options(std::move(o)),
        step_s(ToSeconds(config.step_s)),
        cosim(c, config, CosimOptions(c, config, options)),
        writer(p, topics::Traffic()) {
    const std::vector<maps::District>& districts = c.districts.all();
    AUTODRIVE_THROW_UNLESS(options.districts.size() == districts.size(),
                           "the city has " << districts.size() << " districts, "
                                           << options.districts.size()
                                           << " participants were given for them");
    // The heads by the domain they are heard on: 0 the service's, 1 + i district i's.
    std::vector<std::vector<SignalHeadId>> heads(1 + districts.size());
    for (const SignalHeadId h : cosim.lights().heads()) {
      const maps::District* d = c.districts.Of(c.map.signal_head(h).intersection);
      heads[d == nullptr ? 0 : 1 + static_cast<std::size_t>(d - districts.data())].push_back(h);
    }
    for (std::size_t i = 0; i < heads.size(); ++i) {
      if (heads[i].empty()) continue;
      lamps.push_back(
          std::make_unique<LampInbox>(i == 0 ? p : *options.districts[i - 1], heads[i]));
    }
    for (const dds::Participant* d : options.districts) {
      district_writers.push_back(
          std::make_unique<dds::Writer<msg::TrafficObjects>>(*d, topics::Traffic()));
    }
    district_vehicles.resize(districts.size());
    source = config.lab_cars.source;
    if (source == "auto") source = c.config.sim ? "ground_truth" : "fleet";
    if (source == "ground_truth") {
      std::vector<std::string> names = config.lab_cars.vehicles;
      if (names.empty()) names = SimVehicles(c);
      for (const std::string& n : names) {
        truth_readers.push_back(std::make_unique<dds::Reader<msg::TrackedVehicle>>(
            participant, topics::GroundTruth(ParseVehicleName(n))));
      }
    } else if (source == "eye") {
      fleet_reader =
          std::make_unique<dds::Reader<msg::FleetState>>(participant, topics::EyeFleet());
    } else if (source == "fleet") {
      fleet_reader = std::make_unique<dds::Reader<msg::FleetState>>(participant, topics::Fleet());
    }
    spdlog::info("traffic: lab cars from {}", source);
  }

  void Observe(const msg::TrackedVehicle& v) {
    LabCarPose p;
    p.name = dds::View(v.vehicle_id);
    if (p.name.empty()) return;
    p.position = Eigen::Vector2d(v.pose.pose.position.x, v.pose.pose.position.y);
    const auto& q = v.pose.pose.orientation;
    p.yaw_rad = YawOfQuaternion(q.x, q.y, q.z, q.w);
    p.speed_mps = v.twist.twist.linear.x;
    if (!p.position.allFinite() || !std::isfinite(p.yaw_rad)) return;
    cars[p.name] = p;
    fresh.push_back(std::move(p));
  }

  // Takes what arrived: lamps (reported at `now`) and lab cars.
  void TakeInputs(MonoTime now) {
    for (auto& inbox : lamps) {
      inbox->Take(lamps_taken);
      for (const LampInbox::Lamp& l : lamps_taken) cosim.ReportLamp(l.head, l.lamp, now);
    }
    fresh.clear();
    for (auto& r : truth_readers) {
      while (r->TakeOne(truth_sample)) Observe(*truth_sample);
    }
    if (fleet_reader) {
      while (fleet_reader->TakeOne(fleet_sample)) {
        for (const auto& v : dds::Elements(fleet_sample->vehicles)) Observe(v);
      }
    }
  }

  void Publish(Time stamp) {
    const std::vector<TrafficVehicle>& vehicles = cosim.vehicles();
    msg::TrafficObjects m{};
    FillTrafficObjects(vehicles, stamp, objects, m);
    writer.Write(m);
    if (!district_writers.empty()) {
      for (auto& list : district_vehicles) list.clear();
      for (const TrafficVehicle& v : vehicles) {
        district_vehicles[city.districts.IndexOf(*city.districts.At(v.centre))].push_back(v);
      }
      for (std::size_t i = 0; i < district_writers.size(); ++i) {
        msg::TrafficObjects own{};
        FillTrafficObjects(district_vehicles[i], stamp, objects, own);
        district_writers[i]->Write(own);
      }
    }
    if (options.log != nullptr) {
      std::ostream& log = *options.log;
      const double t = ToSeconds(stamp - Time{});
      for (const TrafficVehicle& v : vehicles) {
        log << fmt::format("{:.3f},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.4f},{:.4f},{},{}\n", t,
                           v.id, v.object_class, v.centre.x(), v.centre.y(), v.yaw_rad, v.speed_mps,
                           v.length_m, v.width_m, v.map_lane, v.signals);
      }
    }
  }

  // One SUMO step at control time `now`, published with `stamp`.
  void Step(MonoTime now, Time stamp) {
    TakeInputs(now);
    cosim.Step(fresh, now);
    Publish(stamp);
  }

  void Report(const char* when) const {
    const CoSimStats& s = cosim.stats();
    spdlog::info(
        "traffic: {} {:.1f} s: {} vehicles, {} lab cars in SUMO, {} departed, {} arrived "
        "({} unplanned), {} teleports, {} collisions",
        when, cosim.time_s(), cosim.vehicles().size(), s.lab_cars_placed, s.departed,
        s.arrived_planned + s.arrived_unplanned, s.arrived_unplanned, s.teleports, s.collisions);
  }

  bool DurationOver() const {
    return options.duration > Duration::zero() &&
           cosim.time_s() >= ToSeconds(options.duration) - 1e-9;
  }

  void RunFollowingClock(const std::atomic<bool>& stop) {
    Clock& clock = *options.clock;
    const ClockReading start = clock.Read();
    const Duration step = FromSeconds(step_s);
    std::int64_t k = 0;
    auto next_report = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!stop.load() && !DurationOver()) {
      const MonoTime due = start.mono + step * (k + 1);
      if (!clock.SleepUntil(due)) {
        if (stop.load()) break;
        const ClockReading r = clock.Read();
        if (r.session != start.session) {
          throw InputError(
              "the simulation restarted (/clock went back): SUMO cannot go back; restart "
              "autodrive-traffic with it");
        }
        continue;
      }
      ++k;
      Step(due, start.ToWire(due));
      if (std::chrono::steady_clock::now() >= next_report) {
        next_report += std::chrono::seconds(10);
        const Duration behind = clock.Monotonic() - due;
        Report(behind > step * 4
                   ? fmt::format("{:.2f} s behind its clock at", ToSeconds(behind)).c_str()
                   : "at");
      }
    }
  }

  // A controller of the simulator's lockstep (common/dds/lockstep.h).
  void RunLockstep(const std::atomic<bool>& stop) {
    dds::LockstepClient lockstep(participant, options.lockstep);
    if (!lockstep.WaitForSimulator(stop)) return;
    // The simulator's reader of the objects (when its traffic is on) before registering, so
    // that the first step's objects reach it.
    (void)writer.WaitForReaders(1, std::chrono::seconds(5));
    if (!lockstep.Register(stop)) return;
    const Duration step = FromSeconds(step_s);
    std::int64_t k = 0;  // SUMO steps run
    auto next_report = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (const std::optional<Time> at = lockstep.NextStep(stop)) {
      const Duration t = *at - Time{};
      // The SUMO steps due by this stamp, each with the inputs as they are now.
      while (step * (k + 1) <= t && !DurationOver()) {
        ++k;
        Step(MonoTime{step * k}, Time{} + step * k);
      }
      if (!writer.WaitForAcks(dds::kLockstepAckTimeout)) {
        spdlog::warn("lockstep: the traffic objects were not acknowledged in {} s",
                     dds::kLockstepAckTimeout.count());
      }
      lockstep.Answer();
      if (std::chrono::steady_clock::now() >= next_report) {
        next_report += std::chrono::seconds(10);
        Report("at");
      }
    }
    if (lockstep.ended()) Report("the simulator ended at");
  }
};

TrafficService::TrafficService(const dds::Participant& participant, const scm::City& city,
                               const TrafficConfig& config, TrafficServiceOptions options)
    : impl_(std::make_unique<Impl>(participant, city, config, std::move(options))) {}

TrafficService::~TrafficService() = default;

void TrafficService::Run(const std::atomic<bool>& stop) {
  if (!impl_->options.lockstep.empty()) {
    impl_->RunLockstep(stop);
  } else {
    AUTODRIVE_THROW_UNLESS(impl_->options.clock != nullptr, "TrafficService needs a clock");
    impl_->RunFollowingClock(stop);
  }
  impl_->Report("stopped at");
}

const CoSimulation& TrafficService::cosim() const { return impl_->cosim; }

}  // namespace autodrive::traffic
