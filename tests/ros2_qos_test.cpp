// ROS 2 nodes' publishers, made as rmw_cyclonedds makes them (tests/ros2_profiles.h: Cyclone's C
// API, none of the project's QoS code), against the real SCM and simulator processes:
// - a SensorDataQoS (best-effort) publisher of a car's ips puts the car in the SCM's fleet, and
//   the SCM reports no incompatible QoS for it;
// - a default-QoS publisher of throttle_command drives the simulated car;
// - a best-effort publisher on the operator request topic, which needs reliable writers, gets
//   one log line and one Event naming RELIABILITY and the QoS to use, within a second.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "autodrive_msgs/msg/FleetState.h"
#include "autodrive_msgs/msg/OperatorRequest.h"
#include "autodrive_msgs/msg/TrackedVehicle.h"
#include "geometry_msgs/msg/Point.h"
#include "std_msgs/msg/Float32.h"

#include "common/config.h"
#include "common/dds/incompatible_qos.h"
#include "common/dds/raw.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "tests/ros2_profiles.h"
#include "tests/scm_processes.h"

namespace autodrive {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using test::RosNodeLike;
using test::RosProfile;
using Clock = std::chrono::steady_clock;

class Ros2Qos : public test::ScmProcesses {};

bool HasCar(const msg::FleetState& fleet, std::string_view id) {
  for (const auto& v : dds::Elements(fleet.vehicles)) {
    if (dds::View(v.vehicle_id) == id) return true;
  }
  return false;
}

TEST_F(Ros2Qos, ASensorDataPublisherOfIpsPutsTheCarInTheFleet) {
  StartInfra();
  StartScm();  // driving_school: nigel_1's ips feeds the fleet
  ASSERT_TRUE(WaitSpat([](const msg::Spat&) { return true; }, seconds(60)));
  dds::Reader<msg::FleetState> fleet(*participant_, dds::topics::Fleet().name,
                                     dds::Qos::Stream(64));
  RosNodeLike ros(partition_);
  const dds_entity_t ips =
      ros.Endpoint(&geometry_msgs_msg_dds__Point__desc, dds::topics::Ips(VehicleId(1)).name,
                   RosProfile::kSensorData, /*writer=*/true);
  // The SCM's ips reader takes best-effort writers: it matches.
  dds_publication_matched_status_t matched{};
  const auto match_deadline = Clock::now() + seconds(30);
  while (matched.current_count == 0 && Clock::now() < match_deadline) {
    dds_get_publication_matched_status(ips, &matched);
    if (matched.current_count == 0) fleet.WaitForData(milliseconds(50));
  }
  ASSERT_EQ(matched.current_count, 1u);
  // 10 Hz, as a positioning system publishes, while the SCM's fleet (10 Hz) is read: of the 50
  // fleet messages after the first with the car, how many have it.
  int with_car = 0;
  int counted = 0;
  bool seen = false;
  auto next = Clock::now();
  const auto deadline = Clock::now() + seconds(60);
  while (counted < 50 && Clock::now() < deadline) {
    if (Clock::now() >= next) {
      msg::Point p{1.0, 0.75, 0.0};
      ASSERT_EQ(dds_write(ips, &p), DDS_RETCODE_OK);
      next += milliseconds(100);
    }
    fleet.WaitForData(milliseconds(20));
    for (const auto& m : fleet.TakeAll()) {
      const bool has = HasCar(*m, "nigel_1");
      seen = seen || has;
      if (!seen) continue;
      ++counted;
      with_car += has ? 1 : 0;
    }
  }
  ASSERT_EQ(counted, 50) << "the car never came into the fleet";
  EXPECT_GE(with_car, 45) << with_car << " of 50 fleet messages had the car";
  std::printf("figure: %d of 50 fleet messages had the car from a sensor_data ips publisher\n",
              with_car);
  // The SCM's reliable ips reader does not take that writer, and says nothing: the best-effort
  // reader beside it does. (Events are latched: whatever it raised is here.) Only ips counts:
  // a test beside this one may have made a best-effort operator request writer in its own
  // partition, which Cyclone reports as a RELIABILITY mismatch before it looks at partitions.
  for (const auto& e : events_->TakeAll()) {
    if (dds::View(e->code) != "incompatible_qos") continue;
    EXPECT_EQ(dds::View(e->message).find("/ips"), std::string_view::npos) << dds::View(e->message);
  }
}

TEST_F(Ros2Qos, ADefaultQosPublisherOfThrottleCommandDrivesTheSimulatedCar) {
  ChildProcess sim({test::Bin("autodrive-sim"), "--city",
                    test::Config("config/cities/driving_school.yaml"), "--partition", partition_,
                    "--log-level", "warn"});
  dds::Reader<msg::TrackedVehicle> truth(*participant_, dds::topics::GroundTruth(VehicleId(1)));
  ASSERT_TRUE(truth.WaitForData(seconds(60)));
  const auto first = truth.TakeAll();
  ASSERT_FALSE(first.empty());
  const double x0 = first.back()->pose.pose.position.x;
  const double y0 = first.back()->pose.pose.position.y;
  RosNodeLike ros(partition_);
  const dds_entity_t throttle =
      ros.Endpoint(&std_msgs_msg_dds__Float32__desc,
                   dds::topics::ThrottleCommand(VehicleId(1)).name, RosProfile::kDefault, true);
  double moved = 0;
  const auto deadline = Clock::now() + seconds(60);
  while (moved < 0.2 && Clock::now() < deadline) {
    msg::Float32 command{0.5f};
    ASSERT_EQ(dds_write(throttle, &command), DDS_RETCODE_OK);
    truth.WaitForData(milliseconds(50));
    for (const auto& m : truth.TakeAll()) {
      moved = std::hypot(m->pose.pose.position.x - x0, m->pose.pose.position.y - y0);
    }
  }
  EXPECT_GE(moved, 0.2) << "the car moved " << moved << " m";
  std::printf("figure: the car moved %.2f m on a default-QoS throttle_command publisher\n", moved);
}

TEST_F(Ros2Qos, ABestEffortOperatorRequestPublisherGetsOneLogLineAndOneEventNamingReliability) {
  StartInfra();
  // As StartScm does, with its log (stderr) on the pipe we read.
  scm_ = std::make_unique<ChildProcess>(
      std::vector<std::string>{
          "/bin/sh", "-c", "exec \"$@\" 2>&1", "sh", test::Bin("autodrive-scm"), "--config",
          test::Config("config/cities/driving_school.yaml"), "--partition", partition_, "--db",
          (dir_ / "scm.db").string(), "--log-level", "warn"},
      std::vector<std::string>{test::NoonTimeZone()});
  ASSERT_TRUE(WaitSpat([](const msg::Spat&) { return true; }, seconds(60)));
  RosNodeLike ros(partition_);
  const auto wall_before = std::chrono::system_clock::now();
  const dds_entity_t request =
      ros.Endpoint(&autodrive_msgs_msg_dds__OperatorRequest__desc,
                   dds::topics::OperatorRequests().name, RosProfile::kSensorData, true);
  ASSERT_GT(request, 0);
  // The event, judged by its stamp (the SCM's wall clock, this host's).
  std::vector<std::string> messages;
  double delay_s = -1;
  const auto deadline = Clock::now() + seconds(30);
  while (messages.empty() && Clock::now() < deadline) {
    events_->WaitForData(milliseconds(100));
    for (const auto& e : events_->TakeAll()) {
      if (dds::View(e->code) != "incompatible_qos") continue;
      messages.emplace_back(dds::View(e->message));
      const auto stamp =
          std::chrono::system_clock::time_point(std::chrono::seconds(e->header.stamp.sec) +
                                                std::chrono::nanoseconds(e->header.stamp.nanosec));
      delay_s = std::chrono::duration<double>(stamp - wall_before).count();
    }
  }
  ASSERT_EQ(messages.size(), 1u);
  EXPECT_THAT(messages[0], ::testing::HasSubstr("/autodrive/scm/operator/request"));
  EXPECT_THAT(messages[0], ::testing::HasSubstr("RELIABILITY"));
  EXPECT_THAT(messages[0], ::testing::HasSubstr("rclcpp::QoS(10)"));
  EXPECT_LE(delay_s, 1.0);
  std::printf("figure: the incompatible_qos event %.3f s after the publisher was made\n", delay_s);
  // A second such publisher is the same reader's second incompatible peer: no more events. A
  // reply to a reliable request, asked after it, shows the SCM has run passes since.
  const dds_entity_t again =
      ros.Endpoint(&autodrive_msgs_msg_dds__OperatorRequest__desc,
                   dds::topics::OperatorRequests().name, RosProfile::kSensorData, true);
  ASSERT_GT(again, 0);
  const auto reply = Scmctl({"status"});
  EXPECT_EQ(reply.code, 0) << reply.text;
  for (const auto& e : events_->TakeAll()) {
    EXPECT_NE(dds::View(e->code), "incompatible_qos") << dds::View(e->message);
  }
  // The log line, in the SCM's own output (read until it ends).
  scm_->Stop();
  std::string log;
  while (auto line = scm_->ReadLine(seconds(30))) log += *line + "\n";
  EXPECT_THAT(log, ::testing::HasSubstr(
                       "incompatible QoS on /autodrive/scm/operator/request: a writer offers less "
                       "RELIABILITY"));
}

}  // namespace
}  // namespace autodrive

// ---- The "Using it from ROS 2" table of docs/messaging.md, acted out --------------------------

namespace autodrive {
namespace {

// A catalogue topic's name as the docs' table shows it: nigel_<n>, signal_<i>, <name>, <camera>.
std::string Shown(const std::string& dds_name) {
  std::string shown = dds::topics::ToRos(dds_name);
  for (const auto& [from, to] :
       std::vector<std::pair<std::string, std::string>>{{"nigel_1", "nigel_<n>"},
                                                        {"signal_1", "signal_<i>"},
                                                        {"/alice/", "/<name>/"},
                                                        {"cameras/overhead", "cameras/<name>"},
                                                        {"eye/overhead", "eye/<camera>"}}) {
    if (const auto at = shown.find(from); at != std::string::npos)
      shown.replace(at, from.size(), to);
  }
  return shown;
}

// "✓" when the ROS endpoint matched ours, "✗ POLICY" when DDS found them incompatible. Where our
// side has two readers (`Qos::reader_accepts_best_effort`), a best-effort ROS writer meets both:
// `pair` waits for both outcomes, and the cell says when rclcpp would also warn.
std::string Outcome(dds_entity_t ros, bool ros_writer, bool pair) {
  const auto deadline = Clock::now() + seconds(20);
  bool matched = false;
  std::string incompatible;
  while (Clock::now() < deadline) {
    std::uint32_t current = 0;
    std::uint32_t bad_count = 0;
    std::int32_t bad_policy = 0;
    if (ros_writer) {
      dds_publication_matched_status_t m{};
      dds_offered_incompatible_qos_status_t bad{};
      dds_get_publication_matched_status(ros, &m);
      dds_get_offered_incompatible_qos_status(ros, &bad);
      current = m.current_count;
      bad_count = bad.total_count;
      bad_policy = static_cast<std::int32_t>(bad.last_policy_id);
    } else {
      dds_subscription_matched_status_t m{};
      dds_requested_incompatible_qos_status_t bad{};
      dds_get_subscription_matched_status(ros, &m);
      dds_get_requested_incompatible_qos_status(ros, &bad);
      current = m.current_count;
      bad_count = bad.total_count;
      bad_policy = static_cast<std::int32_t>(bad.last_policy_id);
    }
    matched = matched || current > 0;
    // PARTITION: a test of another process on this domain (the table's endpoints are in a
    // partition of their own), not this topic's QoS.
    if (bad_count > 0 && incompatible.empty() && bad_policy != DDS_PARTITION_QOS_POLICY_ID) {
      incompatible = dds::QosPolicyName(static_cast<dds_qos_policy_id_t>(bad_policy));
    }
    if (matched && (!pair || !incompatible.empty())) break;
    if (!matched && !incompatible.empty() && !pair) break;
    // Not all yet: discovery is under way (a waitset on both statuses would do the same).
    std::this_thread::sleep_for(milliseconds(10));
  }
  if (matched && pair && !incompatible.empty()) return "✓ (rclcpp warns: " + incompatible + ")";
  if (matched) return "✓";
  if (!incompatible.empty()) return "✗ " + incompatible;
  return "? (neither matched nor incompatible)";
}

std::string TableRow(const dds::topics::CatalogueEntry& t,
                     const std::vector<std::string>& subscribe,
                     const std::vector<std::string>& publish) {
  std::string row = "| `" + Shown(t.name) + "` | " + t.qos.ToString() + " |";
  for (const auto& s : subscribe) row += " " + s + " |";
  for (const auto& p : publish) row += " " + p + " |";
  row += " " + dds::RclcppQosFor(t.qos, false) + " | " + dds::RclcppQosFor(t.qos, true) + " |";
  return row;
}

TEST(Ros2QosTable, EveryTopicMatchesEachRosProfileExactlyAsTheDocsSay) {
  const std::string partition = "ros2_qos_table_" + std::to_string(::getpid());
  // A domain of its own too: the tests beside it (the same topics in other partitions) make
  // DDS report PARTITION incompatibilities, which would hide a cell's policy.
  const auto domain = static_cast<std::uint32_t>(150 + ::getpid() % 80);
  dds::Participant ours(dds::ParticipantOptions{domain, partition, {}});
  std::vector<std::string> rows;
  for (const dds::topics::CatalogueEntry& t : dds::topics::Catalogue()) {
    // Our writer and our reader, as the DDS layer makes them.
    const dds::RawWriter writer(ours, t.name, t.descriptor, t.qos);
    const dds::RawReader reader(ours, t.name, t.descriptor, t.qos);
    RosNodeLike ros(partition, domain);
    std::vector<dds_entity_t> subscriptions;
    std::vector<dds_entity_t> publishers;
    for (const RosProfile p : test::kRosProfiles) {
      subscriptions.push_back(ros.Endpoint(t.descriptor, t.name, p, /*writer=*/false, true));
      publishers.push_back(ros.Endpoint(t.descriptor, t.name, p, /*writer=*/true, true));
    }
    std::vector<std::string> subscribe;
    std::vector<std::string> publish;
    for (const dds_entity_t e : subscriptions) subscribe.push_back(Outcome(e, false, false));
    for (std::size_t i = 0; i < publishers.size(); ++i) {
      // A best-effort ROS writer meets both of a pair's readers (sensor_data is the one).
      const bool pair =
          t.qos.reader_accepts_best_effort && test::kRosProfiles[i] == RosProfile::kSensorData;
      publish.push_back(Outcome(publishers[i], true, pair));
    }
    rows.push_back(TableRow(t, subscribe, publish));
  }
  // The docs' table, between its header and the first line that is not a row.
  const std::string doc = config::ReadFile(test::Config("docs/messaging.md"));
  const std::string marker = "<!-- ros2 qos table: tests/ros2_qos_test.cpp -->";
  const auto at = doc.find(marker);
  ASSERT_NE(at, std::string::npos) << "docs/messaging.md has no " << marker;
  std::vector<std::string> documented;
  std::istringstream lines(doc.substr(at + marker.size()));
  std::string line;
  int header = 0;
  while (std::getline(lines, line)) {
    if (line.empty() && documented.empty() && header == 0) continue;
    if (!line.starts_with("|")) break;
    if (header < 2) {
      ++header;  // the column names and the |---| line
      continue;
    }
    documented.push_back(line);
  }
  std::string table;
  for (const auto& r : rows) table += r + "\n";
  EXPECT_EQ(documented, rows) << "acted out (paste into docs/messaging.md if it is right):\n"
                              << table;
  int differences = 0;
  for (std::size_t i = 0; i < std::max(rows.size(), documented.size()); ++i) {
    if (i >= rows.size() || i >= documented.size() || rows[i] != documented[i]) ++differences;
  }
  std::printf("figure: %zu topics x 8 ROS endpoints acted out, %d rows differ from the docs\n",
              rows.size(), differences);
}

}  // namespace
}  // namespace autodrive
