// SUMO co-simulation as real processes over DDS: autodrive-traffic with the simulator, the SCM
// and its lights, checked only from the wire (TrafficObjects, the lights' reports, /clock) and
// the map, not from SUMO's state or the co-simulation's code.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/ids.h"
#include "maps/map.h"
#include "maps/map_io.h"
#include "tests/scm_processes.h"

namespace autodrive::test {
namespace {

using std::chrono::seconds;

class TrafficSystem : public ScmProcesses {};

// Every message's objects, as the test saw them.
struct Seen {
  double t = 0;  // the message's stamp (simulated s)
  std::string id, lane;
  double x = 0, y = 0, yaw = 0, speed = 0;
};

// The lamp a head showed over simulated time: (time it came on, lamp).
using LampHistory = std::vector<std::pair<double, int>>;

int LampAt(const LampHistory& h, double t) {
  int lamp = -1;
  for (const auto& [since, l] : h) {
    if (since > t) break;
    lamp = l;
  }
  return lamp;
}

// True when the head showed steady red over [t - before, t]: red throughout, and nothing else
// in the second before.
bool SteadyRed(const LampHistory& h, double t, double before) {
  for (const auto& [since, l] : h) {
    if (since > t) break;
    if (since > t - before - 1.0 && l != 1) return false;
  }
  return LampAt(h, t - before) == 1 && LampAt(h, t) == 1;
}

// The small town as shipped, but its overhead camera nearly off (nobody looks at it here).
// Without `lab_cars`, the lab's cars are left out of SUMO (`lab_cars.source: none`) and SUMO's
// out of the simulator: the lab's cars stand at their spawns, and the lights are the subject.
std::string TestCity(const std::filesystem::path& dir, bool lab_cars = false) {
  std::string text = config::ReadFile(Config("config/cities/small_town.yaml"));
  const auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    if (at == std::string::npos) throw std::runtime_error("small_town.yaml: no " + from);
    text.replace(at, from.size(), to);
  };
  replace("../maps/", Config("config/maps") + "/");
  replace("../cameras/", Config("config/cameras") + "/");
  replace("rate_hz: 15", "rate_hz: 1");
  if (!lab_cars) {
    replace("traffic:\n", "traffic:\n  lab_cars: {source: none}\n");
    // ... and the SUMO cars out of the simulator's world, or they would drive through them.
    replace("sim:\n", "sim:\n  service: {traffic: false}\n");
  }
  const std::string city = (dir / "city.yaml").string();
  std::ofstream(city) << text;
  return city;
}

TEST_F(TrafficSystem, SumoCarsCallActuatedGroupsNeverCrossOnRedAndStopAtAFlashingCentre) {
  const std::string city = TestCity(dir_);
  const maps::Map map = maps::LoadMapOrLayout(Config("config/maps/small_town.yaml"));
  dds::Reader<msg::TrafficObjects> traffic(*participant_, dds::topics::Traffic().name,
                                           dds::Qos::Stream(64));
  // Every /clock kept (it places the lamps' samples in time, below), also through a `scmctl` call.
  dds::Reader<msg::Clock> clock(*participant_, dds::topics::Clock().name,
                                dds::Qos::BestEffortStream(8192));
  // The lamps each light showed, from its own reports (`DeviceStatus`: the aspect it shows,
  // stamped by the light with the simulated time at which it showed it). Not `signal_<i>/state`
  // timed by when this test reads it: in lockstep the clock runs about six times faster than the
  // wall, so this test's read lag (a `scmctl` call, a busy machine) of 50 ms would move a lamp
  // change by 0.3 simulated seconds, and a car that entered on an early green would count as
  // entering on red. Flash is kept apart from steady red (as `-mode`).
  // Deep: the 14 devices report ten times a second, and nothing is read during a `scmctl` call.
  dds::Reader<msg::DeviceStatus> devices(*participant_, dds::topics::Devices().name,
                                         dds::Qos::Stream(8192));
  std::map<int, LampHistory> history;
  // And `signal_<i>/state` itself, each sample with its DDS source time (wall clock, this host),
  // placed in simulated time through /clock's own source times: the reports above must agree.
  std::map<int, std::unique_ptr<dds::Reader<msg::Int32>>> lamps;
  for (const maps::SignalHead& h : map.signal_heads) {
    lamps[static_cast<int>(h.id.value())] =
        std::make_unique<dds::Reader<msg::Int32>>(*participant_, dds::topics::SignalState(h.id));
  }
  std::vector<std::pair<std::int64_t, double>> clock_at;   // (source ns, simulated s)
  std::vector<std::tuple<int, std::int64_t, int>> states;  // (head, source ns, lamp)
  StartInfra("small_town", {"--clock", "sim"});
  StartScm(city, {"--clock", "sim"});
  // Ten simulated minutes in lockstep with the traffic as the controller.
  ChildProcess sim({Bin("autodrive-sim"), "--city", city, "--partition", partition_, "--mode",
                    "lockstep", "--controller", "traffic", "--duration", "600", "--log-level",
                    "warn"});
  ChildProcess cosim({Bin("autodrive-traffic"), "--city", city, "--partition", partition_,
                      "--lockstep", "traffic", "--work-dir", (dir_ / "traffic").string(),
                      "--log-level", "warn"});
  // Minutes 0 to 4 on the actuated plan (a group goes green only when a car calls it), 4 to 7
  // on the fixed-time plan, 7 to 10 with the centre in flash.
  for (const std::string x : {"centre", "north_t"}) {
    const Output r = Lab({"plan", x, "evening"});
    ASSERT_EQ(r.code, 0) << r.text;
  }
  std::vector<Seen> seen;
  std::set<std::size_t> counts;  // vehicles per message, once all are in
  double now = 0, flash_at = -1, fixed_at = -1;
  const auto deadline = SteadyClock::now() + std::chrono::minutes(12);
  bool ended = false;
  while (SteadyClock::now() < deadline && !ended) {
    traffic.WaitForData(std::chrono::milliseconds(5));
    dds::Message<msg::Clock> c;
    dds::SampleInfo info;
    while (clock.TakeOne(c, &info)) {
      const double t = ToSeconds(dds::FromMsg(c->clock) - Time{});
      now = std::max(now, t);
      clock_at.emplace_back(info.source_timestamp_ns, t);
    }
    for (auto& [head, reader] : lamps) {
      dds::Message<msg::Int32> m;
      while (reader->TakeOne(m, &info))
        states.emplace_back(head, info.source_timestamp_ns, m->data);
    }
    while (auto d = devices.TakeOne()) {
      const std::string id(dds::View((*d)->device_id));
      if (id.rfind("signal_", 0) != 0) continue;
      const int head = std::stoi(id.substr(7));
      const double t = ToSeconds(dds::FromMsg((*d)->header.stamp) - Time{});
      const int lamp = (*d)->mode == autodrive_msgs_msg_DeviceStatus_Constants_NORMAL
                           ? (*d)->displayed_state
                           : -(*d)->mode;
      auto& h = history[head];
      if (h.empty() || h.back().second != lamp) h.emplace_back(t, lamp);
    }
    while (auto m = traffic.TakeOne()) {
      const double t = ToSeconds(dds::FromMsg((*m)->header.stamp) - Time{});
      const auto objects = dds::Elements((*m)->objects);
      if (t > 5) counts.insert(objects.size());
      for (const auto& o : objects) {
        const auto& q = o.pose.orientation;
        seen.push_back(Seen{
            t, std::string(dds::View(o.object_id)), std::string(dds::View(o.map_lane_id)),
            o.pose.position.x, o.pose.position.y,
            std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)), o.speed_mps});
      }
    }
    if (fixed_at < 0 && now >= 240) {
      for (const std::string x : {"centre", "north_t"}) {
        const Output r = Lab({"plan", x, "day"});
        ASSERT_EQ(r.code, 0) << r.text;
      }
      fixed_at = now;
    }
    if (flash_at < 0 && now >= 420) {
      // The last three minutes with the centre in flash.
      const Output r = Lab({"mode", "centre", "flash"});
      ASSERT_EQ(r.code, 0) << r.text;
      flash_at = now;
    }
    ended = sim.Wait(std::chrono::milliseconds(0)).has_value();
  }
  ASSERT_TRUE(ended) << "the simulator did not finish 600 simulated seconds in 12 minutes";

  // Every steady lamp `signal_<i>/state` showed (outside flash) is in the light's stamped
  // reports, at most a second of simulated time before the last /clock sent before the state
  // was written (the light's clock lags what was sent by /clock's delivery, never leads it; a
  // /clock lost on its way here places a state up to a step early).
  std::sort(clock_at.begin(), clock_at.end());
  int states_checked = 0, states_unmatched = 0;
  double worst_lag = 0;
  for (const auto& [head, source_ns, lamp] : states) {
    const auto after =
        std::upper_bound(clock_at.begin(), clock_at.end(),
                         std::make_pair(source_ns, std::numeric_limits<double>::infinity()));
    if (after == clock_at.begin() || lamp < 1 || lamp > 3) continue;
    const double t = std::prev(after)->second;
    const LampHistory& h = history[head];
    const auto steady = [](int l) { return l >= 1 && l <= 3; };  // not flashing, dark, off
    if (t < 15 || !steady(LampAt(h, t)) || !steady(LampAt(h, t - 1.0))) continue;
    ++states_checked;
    std::optional<double> reported;  // the latest report of that lamp in the window
    for (const auto& [since, l] : h) {
      if (l == lamp && since <= t + 0.2 && since >= t - 1.0) reported = since;
    }
    if (reported) {
      worst_lag = std::max(worst_lag, t - *reported);
    } else {
      ++states_unmatched;
      ADD_FAILURE() << "signal_" << head << "/state showed " << lamp << " at about " << t
                    << " s: not in its reports";
    }
  }
  std::printf("signal_<i>/state: %d steady lamps, %d not in the lights' reports (lag <= %.2f s)\n",
              states_checked, states_unmatched, worst_lag);
  EXPECT_GT(states_checked, 100);
  EXPECT_EQ(cosim.Wait(seconds(30)), 0) << "autodrive-traffic saw a collision, a teleport or a "
                                           "vehicle lost (its exit code)";
  ASSERT_GT(flash_at, 0);
  // No vehicle lost: 30 in every message once they are in.
  EXPECT_EQ(counts, (std::set<std::size_t>{30})) << "vehicles per message changed";

  // Crossings: a vehicle's lane goes from an ingress lane of a signalised intersection to one of
  // its movements between two messages.
  std::map<std::string, const maps::Lane*> lanes;
  std::map<std::string, const maps::Movement*> movements;
  for (const maps::Lane& l : map.lanes) lanes.emplace(l.name, &l);
  for (const maps::Movement& m : map.movements) movements.emplace(m.name, &m);
  std::map<std::string, Seen> last;
  std::map<std::string, double> stood;  // last time each vehicle stood still
  int on_green = 0, on_red = 0, in_flash = 0, flash_without_stop = 0;
  std::map<int, int> per_minute;  // crossings at every intersection
  for (const Seen& s : seen) {
    if (s.speed < 0.01) stood[s.id] = s.t;
    const auto before = last.find(s.id);
    const auto m = movements.find(s.lane);
    if (before != last.end() && m != movements.end() && lanes.count(before->second.lane) != 0) {
      ++per_minute[static_cast<int>(s.t / 60)];
      const maps::Intersection& x = map.intersection(m->second->intersection);
      if (x.control == maps::Control::kSignal && s.t > 15) {
        // The head of this intersection that faces the movement's approach.
        const maps::SignalHead* head = nullptr;
        for (const maps::SignalHead& h : map.signal_heads) {
          if (h.intersection == x.id && h.approach == m->second->from_approach) head = &h;
        }
        ASSERT_NE(head, nullptr) << s.lane;
        const LampHistory& h = history[static_cast<int>(head->id.value())];
        if (x.name == "centre" && s.t > flash_at + 5) {
          ++in_flash;
          const auto st = stood.find(s.id);
          if (st == stood.end() || s.t - st->second > 1.5) {
            ++flash_without_stop;
            ADD_FAILURE() << s.id << " entered " << s.lane << " at " << s.t
                          << " s in flash without stopping";
          }
        } else if (x.name != "centre" || s.t < flash_at) {
          if (SteadyRed(h, s.t, 0.3)) {
            ++on_red;
            std::ostringstream detail;
            for (const auto& [since, l] : h) {
              if (since > s.t - 8 && since < s.t + 2) detail << " " << since << ":" << l;
            }
            for (const Seen& o : seen) {
              if (o.id == s.id && o.t > s.t - 1 && o.t < s.t + 0.2) {
                detail << "\n  " << o.t << " " << o.lane << " v=" << o.speed;
              }
            }
            ADD_FAILURE() << s.id << " entered " << s.lane << " at " << s.t << " s on red (head "
                          << head->id.value() << ")" << detail.str();
          }
          if (LampAt(h, s.t) == 3) ++on_green;
        }
      }
    }
    last[s.id] = s;
  }
  for (const auto& [minute, n] : per_minute) std::printf("minute %d: %d crossings\n", minute, n);
  std::printf(
      "crossings: %d on green, %d on red, %d at the flashing centre (%d without stopping)\n",
      on_green, on_red, in_flash, flash_without_stop);
  EXPECT_GT(on_green, 50);
  EXPECT_EQ(on_red, 0);
  // The flashing centre is an all-way stop: cars go through it, each after stopping.
  EXPECT_GT(in_flash, 10);
  EXPECT_EQ(flash_without_stop, 0);
  // The town keeps moving (no gridlock): every minute cars cross.
  for (int minute = 0; minute < 10; ++minute) {
    EXPECT_GE(per_minute[minute], 20) << "minute " << minute << ": the traffic stood still";
  }

  // Actuated: the SUMO cars call their groups. A group turns green only while a car is on its
  // approach (in its detector zone; the check here: on the approach's lane in the seconds
  // before), which a fixed-time plan does not wait for.
  const auto green_onsets = [&](double from, double to, int& total, int& without_car) {
    total = without_car = 0;
    for (const maps::SignalHead& h : map.signal_heads) {
      const maps::Intersection& x = map.intersection(h.intersection);
      std::set<std::string> ingress;
      for (const maps::Approach& a : x.approaches) {
        if (a.id != h.approach) continue;
        for (const LaneId l : a.ingress) ingress.insert(map.lane(l).name);
      }
      int before = -1;
      for (const auto& [t, lamp] : history[static_cast<int>(h.id.value())]) {
        if (lamp == 3 && before != 3 && t >= from && t < to) {
          ++total;
          const bool car = std::any_of(seen.begin(), seen.end(), [&](const Seen& s) {
            return s.t >= t - 8.0 && s.t <= t && ingress.count(s.lane) != 0;
          });
          if (!car) ++without_car;
        }
        before = lamp;
      }
    }
  };
  int actuated = 0, actuated_without_car = 0, fixed = 0, fixed_without_car = 0;
  green_onsets(20, fixed_at, actuated, actuated_without_car);
  green_onsets(fixed_at + 20, flash_at, fixed, fixed_without_car);
  std::printf("green onsets: actuated %d (%d with no car on the approach), fixed-time %d (%d)\n",
              actuated, actuated_without_car, fixed, fixed_without_car);
  EXPECT_GT(actuated, 10);
  EXPECT_EQ(actuated_without_car, 0) << "an actuated group went green with no car calling it";
}

// Two lockstep runs with the same seed publish the same objects. The lights are left out (they
// are not in lockstep): the signalised intersections stay dark, all-way stops.
TEST_F(TrafficSystem, TwoLockstepRunsWithTheSameSeedPublishTheSameObjects) {
  const std::string city = Config("config/cities/small_town.yaml");
  const auto run = [&](const std::string& name) {
    const std::string log = (dir_ / (name + ".csv")).string();
    ChildProcess sim({Bin("autodrive-sim"), "--city", city, "--partition", partition_ + name,
                      "--mode", "lockstep", "--controller", "traffic", "--duration", "60",
                      "--log-level", "warn"});
    ChildProcess cosim({Bin("autodrive-traffic"), "--city", city, "--partition", partition_ + name,
                        "--lockstep", "traffic", "--log", log, "--work-dir", (dir_ / name).string(),
                        "--log-level", "warn"});
    EXPECT_EQ(sim.Wait(std::chrono::minutes(5)), 0);
    EXPECT_EQ(cosim.Wait(seconds(60)), 0);
    return config::ReadFile(log);
  };
  const std::string a = run("a"), b = run("b");
  EXPECT_GT(std::count(a.begin(), a.end(), '\n'), 25000);  // 30 vehicles, ~1,000 steps
  EXPECT_TRUE(a == b) << "the two runs differ";
}

// An oriented rectangle on the ground: centre, heading, half length and half width.
struct Footprint {
  Eigen::Vector2d centre;
  double yaw = 0, half_length = 0, half_width = 0;
};

// How deep two footprints overlap (the smallest overlap over the separating axes); negative
// when they are apart.
double Penetration(const Footprint& a, const Footprint& b) {
  double depth = std::numeric_limits<double>::infinity();
  const auto axes = [](const Footprint& f) {
    return std::array<Eigen::Vector2d, 2>{Eigen::Vector2d(std::cos(f.yaw), std::sin(f.yaw)),
                                          Eigen::Vector2d(-std::sin(f.yaw), std::cos(f.yaw))};
  };
  const auto ax = axes(a), bx = axes(b);
  const auto radius = [](const Footprint& f, const std::array<Eigen::Vector2d, 2>& fx,
                         const Eigen::Vector2d& n) {
    return f.half_length * std::abs(fx[0].dot(n)) + f.half_width * std::abs(fx[1].dot(n));
  };
  for (const auto& n : {ax[0], ax[1], bx[0], bx[1]}) {
    depth = std::min(depth,
                     radius(a, ax, n) + radius(b, bx, n) - std::abs((b.centre - a.centre).dot(n)));
  }
  return depth;
}

// Four lab cars driven by the example driver (its LIDAR, the lamps, the map) among SUMO's 30
// cars, all in lockstep, the SCM running the lights: nothing touches. Checked from the wire,
// not from SUMO's or the simulator's own reports: each lab car's footprint from its ground
// truth against every SUMO car's from TrafficObjects, as the simulator had them over that
// period. And the lab cars keep driving: no one stands still for long.
TEST_F(TrafficSystem, FourDrivenLabCarsAndThirtySumoCarsNeverTouch) {
  constexpr double kMinutes = 5;
  const std::string city = TestCity(dir_, /*lab_cars=*/true);
  dds::Reader<msg::TrafficObjects> traffic(*participant_, dds::topics::Traffic().name,
                                           dds::Qos::Stream(256));
  std::vector<std::unique_ptr<dds::Reader<msg::TrackedVehicle>>> truths;
  for (std::uint32_t i = 1; i <= 4; ++i) {
    truths.push_back(std::make_unique<dds::Reader<msg::TrackedVehicle>>(
        *participant_, dds::topics::GroundTruth(VehicleId(i)).name, dds::Qos::Stream(256)));
  }
  StartInfra("small_town", {"--clock", "sim"});
  StartScm(city, {"--clock", "sim"});
  ChildProcess sim({Bin("autodrive-sim"), "--city", city, "--partition", partition_, "--mode",
                    "lockstep", "--controller", "traffic", "--controller", "driver", "--duration",
                    std::to_string(static_cast<int>(kMinutes * 60)), "--log-level", "warn"});
  ChildProcess driver({Bin("autodrive-example-driver"), "--city", city, "--partition", partition_,
                       "--lockstep", "driver", "--log-level", "warn"});
  ChildProcess cosim({Bin("autodrive-traffic"), "--city", city, "--partition", partition_,
                      "--lockstep", "traffic", "--work-dir", (dir_ / "traffic").string(),
                      "--log-level", "warn"});
  // Nigel (NIGEL.md): 0.318 x 0.175 m, the body's centre 0.07077 m ahead of the rear axle.
  constexpr double kAhead = 0.07077, kHalfLength = 0.318 / 2, kHalfWidth = 0.175 / 2;
  const auto step_of = [](double t) { return std::lround(t / 0.05); };
  std::map<long, std::vector<Footprint>> sumo;  // by step: the SUMO cars as published
  std::set<std::size_t> counts;                 // vehicles per message, once all are in
  std::array<double, 4> driven{}, standing_since{}, longest_stand{};
  std::array<std::optional<Eigen::Vector2d>, 4> last, stood_at;
  long pairs = 0, contacts = 0;
  double worst = -1;  // deepest overlap seen
  const auto deadline = SteadyClock::now() + std::chrono::minutes(20);
  bool ended = false;
  while (SteadyClock::now() < deadline && !ended) {
    traffic.WaitForData(std::chrono::milliseconds(5));
    while (auto m = traffic.TakeOne()) {
      const double t = ToSeconds(dds::FromMsg((*m)->header.stamp) - Time{});
      std::vector<Footprint>& boxes = sumo[step_of(t)];
      for (const auto& o : dds::Elements((*m)->objects)) {
        const auto& q = o.pose.orientation;
        boxes.push_back(
            Footprint{Eigen::Vector2d(o.pose.position.x, o.pose.position.y),
                      std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)),
                      o.size.x / 2, o.size.y / 2});
      }
      if (t > 5) counts.insert(boxes.size());
    }
    for (std::size_t i = 0; i < truths.size(); ++i) {
      while (auto m = truths[i]->TakeOne()) {
        const double t = ToSeconds(dds::FromMsg((*m)->observed) - Time{});
        const auto& p = (*m)->pose.pose;
        const double yaw = std::atan2(2 * (p.orientation.w * p.orientation.z),
                                      1 - 2 * p.orientation.z * p.orientation.z);
        const Eigen::Vector2d at(p.position.x, p.position.y);
        if (last[i]) driven[i] += (at - *last[i]).norm();
        last[i] = at;
        if (!stood_at[i] || (at - *stood_at[i]).norm() > 0.02) {
          stood_at[i] = at;
          standing_since[i] = t;
        }
        longest_stand[i] = std::max(longest_stand[i], t - standing_since[i]);
        // The simulator moved the car to here over its last control period among the SUMO cars
        // of the newest message at the period's start: the last one stamped before now.
        auto before = sumo.lower_bound(step_of(t));
        if (before == sumo.begin()) continue;
        --before;
        const Footprint lab{at + kAhead * Eigen::Vector2d(std::cos(yaw), std::sin(yaw)), yaw,
                            kHalfLength, kHalfWidth};
        for (const Footprint& b : before->second) {
          ++pairs;
          const double depth = Penetration(lab, b);
          worst = std::max(worst, depth);
          if (depth > 0.001 && ++contacts <= 5) {
            ADD_FAILURE() << "nigel_" << i + 1 << " at (" << at.x() << ", " << at.y() << ") and a "
                          << "SUMO car at (" << b.centre.x() << ", " << b.centre.y()
                          << ") overlap by " << depth << " m at " << t << " s";
          }
        }
      }
    }
    // What no truth can still need.
    if (sumo.size() > 200) sumo.erase(sumo.begin());
    ended = sim.Wait(std::chrono::milliseconds(0)).has_value();
  }
  ASSERT_TRUE(ended) << "the simulator did not finish in 20 minutes";
  EXPECT_EQ(cosim.Wait(seconds(30)), 0) << "autodrive-traffic saw a collision (SUMO's junction "
                                           "checks), a teleport or a vehicle lost (its exit code)";
  driver.Stop();
  EXPECT_EQ(counts, (std::set<std::size_t>{30})) << "vehicles per message changed";
  std::printf("%ld lab-SUMO pairs checked, %ld overlaps; closest: %.3f m %s\n", pairs, contacts,
              std::abs(worst), worst > 0 ? "deep" : "apart");
  // Each lab car against each SUMO car at (nearly) every step.
  EXPECT_GT(pairs, static_cast<long>(4 * 30 * kMinutes * 60 / 0.05 * 0.9));
  EXPECT_EQ(contacts, 0);
  for (std::size_t i = 0; i < 4; ++i) {
    std::printf("nigel_%zu drove %.1f m; stood still for at most %.0f s at a time\n", i + 1,
                driven[i], longest_stand[i]);
    // Free, it would drive 0.156 m/s x 300 s = 47 m; lights, stop signs and queues take
    // their share (in runs: 22 to 28 m, stands of up to 50 s).
    EXPECT_GT(driven[i], 8.0) << "nigel_" << i + 1;
    EXPECT_LT(longest_stand[i], 120.0) << "nigel_" << i + 1 << " stood still: a deadlock";
  }
}

// A free TCP port on localhost.
int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
  socklen_t len = sizeof(addr);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

// SUMO as a TraCI server: SUMO's own Python client (Debian's sumo-tools) attaches as a second
// client and reads the vehicles autodrive-traffic publishes.
TEST_F(TrafficSystem, ASecondTraciClientAttachesAndReadsTheSameVehicles) {
  // No simulator here: with the lab's cars left out, the background cars go in at once (they
  // would wait up to 5 s for the simulator's cars otherwise).
  const std::string city = TestCity(dir_);
  const int port = FreePort();
  const std::string script = (dir_ / "client.py").string();
  std::ofstream(script) << R"(import sys
sys.path.append('/usr/share/sumo/tools')
import traci
traci.init(int(sys.argv[1]), numRetries=100)
traci.setOrder(2)
for step in range(1, 201):
    traci.simulationStep()
    if step % 50 == 0:
        t = traci.simulation.getTime()
        for v in sorted(traci.vehicle.getIDList()):
            x, y = traci.vehicle.getPosition(v)
            print('V %.2f %s %.4f %.4f %.4f' % (t, v, x, y, traci.vehicle.getLength(v)), flush=True)
traci.close()
)";
  dds::Reader<msg::TrafficObjects> traffic(*participant_, dds::topics::Traffic().name,
                                           dds::Qos::Stream(512));
  ChildProcess cosim({Bin("autodrive-traffic"), "--city", city, "--partition", partition_,
                      "--traci-port", std::to_string(port), "--clients", "2", "--duration", "10",
                      "--work-dir", (dir_ / "traffic").string(), "--log-level", "warn"});
  ChildProcess client({"python3", script, std::to_string(port)});
  std::vector<std::string> lines;
  // The vehicles' lines ("V ..."); traci also prints its own ("Retrying in 1 seconds").
  while (auto line = client.ReadLine(std::chrono::minutes(2))) {
    if (line->rfind("V ", 0) == 0) lines.push_back(line->substr(2));
  }
  EXPECT_EQ(client.Wait(seconds(30)), 0);
  EXPECT_EQ(cosim.Wait(seconds(60)), 0);
  ASSERT_EQ(lines.size(), 4u * 30u)
      << "the Python client saw " << static_cast<double>(lines.size()) / 4.0 << " vehicles a time";
  // The same vehicles at the same times. Message k (stamped k steps of 50 ms after the first)
  // is SUMO's state at (k + 1) x 50 ms; SUMO's position is the front bumper in the 14x frame:
  // the object's centre plus half its length ahead, times 14. (Should this reader have
  // matched only after the first messages went out, the first it has is a later step: the
  // offset that matches the client's lines is found below.)
  std::map<long, std::map<std::string, std::array<double, 3>>> published;  // step: id: x, y, yaw
  std::optional<Time> first;
  for (auto& m : traffic.TakeAll()) {
    const Time stamp = dds::FromMsg(m->header.stamp);
    if (!first) first = stamp;
    const long step = std::lround(ToSeconds(stamp - *first) / 0.05) + 1;
    for (const auto& o : dds::Elements(m->objects)) {
      const auto& q = o.pose.orientation;
      const double yaw = std::atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z));
      published[step][std::string(dds::View(o.object_id))] = {
          o.pose.position.x + std::cos(yaw) * o.size.x / 2,
          o.pose.position.y + std::sin(yaw) * o.size.x / 2, yaw};
    }
  }
  ASSERT_TRUE(first.has_value()) << "no TrafficObjects received";
  struct Line {
    double t = 0, x = 0, y = 0, length = 0;
    std::string id;
  };
  std::vector<Line> seen;
  for (const std::string& l : lines) {
    std::istringstream in(l);
    Line& v = seen.emplace_back();
    in >> v.t >> v.id >> v.x >> v.y >> v.length;
  }
  // Messages missed at the start (at most a second's): the offset under which the most lines
  // match; all must match under it.
  const auto matches = [&](const Line& v, long missed) {
    const auto step = published.find(std::lround(v.t / 0.05) - missed);
    if (step == published.end()) return false;
    const auto o = step->second.find(v.id);
    return o != step->second.end() && std::abs(o->second[0] * 14.0 - v.x) < 1e-3 &&
           std::abs(o->second[1] * 14.0 - v.y) < 1e-3;
  };
  long missed = 0;
  std::size_t best = 0;
  for (long m = 0; m <= 20; ++m) {
    const auto n = static_cast<std::size_t>(
        std::count_if(seen.begin(), seen.end(), [&](const Line& v) { return matches(v, m); }));
    if (n > best) {
      best = n;
      missed = m;
    }
  }
  if (missed != 0)
    std::printf("(the first %ld TrafficObjects went out before the reader matched)\n", missed);
  std::size_t matched = 0;
  for (const Line& v : seen) {
    const std::string l =
        (std::ostringstream() << v.t << ' ' << v.id << ' ' << v.x << ' ' << v.y).str();
    EXPECT_NEAR(v.length / 14.0, 0.318, 1e-6) << l;
    const double t = v.t, x = v.x, y = v.y;
    const std::string& id = v.id;
    const auto step = published.find(std::lround(t / 0.05) - missed);
    ASSERT_NE(step, published.end()) << "no message for " << t << " s";
    const auto o = step->second.find(id);
    ASSERT_NE(o, step->second.end()) << id << " at " << t << " s is not in TrafficObjects";
    EXPECT_NEAR(o->second[0] * 14.0, x, 1e-3) << l;
    EXPECT_NEAR(o->second[1] * 14.0, y, 1e-3) << l;
    ++matched;
  }
  EXPECT_EQ(matched, 120u);
}

}  // namespace
}  // namespace autodrive::test
