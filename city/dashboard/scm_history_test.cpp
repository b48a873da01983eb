// The dashboard against a real SCM (in-process, on its own DDS partition and database): the event
// log reaches the page with every field as the SCM logged it, read from the SCM's typed reply
// (no text is parsed), and scmctl --json carries the same fields.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "city/dashboard/feed.h"
#include "city/dashboard/hub.h"
#include "city/dashboard/server.h"

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/message.h"
#include "common/dds/participant.h"
#include "common/test_support.h"
#include "scm/daemon.h"
#include "scm/operator/client.h"
#include "scm/store/store.h"

// Last: it brings <resolv.h>, whose `_res` macro breaks Eigen's headers included after it.
#include <httplib.h>

namespace autodrive::dashboard {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

class DashboardWithScm : public ::testing::Test {
 protected:
  DashboardWithScm()
      : partition_(fmt::format("dashboard_scm_{}", ::getpid())),
        dir_(std::filesystem::temp_directory_path() / partition_) {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~DashboardWithScm() override { std::filesystem::remove_all(dir_); }

  /// The Driving School with its map path made absolute, not waiting for lights (none here).
  std::filesystem::path City() const {
    std::string text = config::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
    const std::string map =
        (test::SourceDir() / "config/maps/driving_school.yaml").lexically_normal().string();
    text.replace(text.find("map: ../maps/driving_school.yaml"), 32, "map: " + map);
    text += "\ndevices: {wait_for_lights: false}\n";
    const auto path = dir_ / "city.yaml";
    std::ofstream(path) << text;
    return path;
  }

  std::string partition_;
  std::filesystem::path dir_;
};

/// An event of a light host, in the SCM's log: about an intersection and a device, raised by
/// another source than the SCM.
scm::EventRecord LampFault() {
  scm::EventRecord e;
  e.time = TimeFromSeconds(1795240000.125);
  e.severity = scm::Severity::kAlarm;
  e.source = "infra/lights_east";
  e.code = "lamp_fault";
  e.message = "signal_3: red lamp out";
  e.intersection = IntersectionId(7);
  e.device_id = "signal_3";
  e.actor = "infra/lights_east";
  e.active = true;
  return e;
}

TEST_F(DashboardWithScm, AnEventReachesThePageAndScmctlJsonWithEveryFieldAsTheScmLoggedIt) {
  const scm::EventRecord logged = LampFault();
  std::int64_t id = 0;
  {
    scm::Store store((dir_ / "scm.db").string());
    id = store.AppendEvent(logged);
  }
  scm::ScmOptions options;
  options.config_path = City();
  options.db_path = (dir_ / "scm.db").string();
  options.config_root = test::SourceDir();
  dds::Participant scm_participant(dds::ParticipantOptions{{}, partition_, {}});
  WallClock clock;
  scm::Scm scm(options, clock, scm_participant);
  std::thread loop([&] { scm.Run(); });

  dds::Participant participant(dds::ParticipantOptions{{}, partition_, {}});
  Hub hub(json::object(), json::array(), /*actions_need_token=*/true);
  ServerOptions server_options;
  server_options.port = 0;
  Server server(participant, hub, server_options, [] { return json::object(); });
  server.Start();
  httplib::Client http("127.0.0.1", server.port());
  http.set_read_timeout(30, 0);

  // The page's history: GET /api/events, until the SCM answers (discovery takes a moment).
  json page;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (std::chrono::steady_clock::now() < deadline) {
    const auto res = http.Get("/api/events?limit=50");
    if (res && res->status == 200) {
      page = json::parse(res->body);
      break;
    }
  }
  ASSERT_TRUE(page.contains("events")) << page.dump();
  const json* shown = nullptr;
  for (const json& e : page["events"]) {
    if (e.value("code", "") == "lamp_fault") shown = &e;
  }
  ASSERT_NE(shown, nullptr) << page.dump();
  EXPECT_EQ((*shown)["id"], id);
  EXPECT_DOUBLE_EQ((*shown)["stamp"].get<double>(), ToSeconds(logged.time));
  EXPECT_EQ((*shown)["severity"], 2) << "the page's scale: 2 alarm";
  EXPECT_EQ((*shown)["source"], "infra/lights_east");
  EXPECT_EQ((*shown)["code"], "lamp_fault");
  EXPECT_EQ((*shown)["message"], "signal_3: red lamp out");
  EXPECT_EQ((*shown)["intersection"], 7);
  EXPECT_EQ((*shown)["device"], "signal_3");
  EXPECT_EQ((*shown)["active"], true);

  // The same event on the wire, as the live feed shows it: the same object.
  dds::Message<msg::Event> live;
  live->header.stamp = dds::ToMsg(logged.time);
  live->event_id = static_cast<std::uint64_t>(id);
  live->severity = scm::ToWire(logged.severity);
  dds::SetString(live->source, logged.source);
  dds::SetString(live->code, logged.code);
  dds::SetString(live->message, logged.message);
  live->intersection_id = logged.intersection.value();
  dds::SetString(live->device_id, logged.device_id);
  live->active = logged.active;
  json from_wire = EventJson(*live);
  from_wire["acked_by"] = nullptr;
  EXPECT_EQ(*shown, from_wire);

  // What `scmctl --json events` prints: the same fields, and the actor.
  {
    scm::OperatorClient client(participant, scm::UniqueClientId("dashboard_scm_test"));
    ASSERT_TRUE(client.WaitForScm(30s));
    const auto answer = client.Call("events", {{"limit", "50"}}, 30s);
    ASSERT_TRUE(answer);
    const json printed = scm::ToJson(*answer);
    ASSERT_TRUE(printed["values"].contains(std::to_string(id))) << printed.dump();
    const json& e = printed["values"][std::to_string(id)];
    EXPECT_EQ(e["id"], id);
    EXPECT_DOUBLE_EQ(e["stamp"].get<double>(), ToSeconds(logged.time));
    EXPECT_EQ(e["severity"], "alarm");
    EXPECT_EQ(e["source"], "infra/lights_east");
    EXPECT_EQ(e["code"], "lamp_fault");
    EXPECT_EQ(e["message"], "signal_3: red lamp out");
    EXPECT_EQ(e["intersection"], 7);
    EXPECT_EQ(e["device"], "signal_3");
    EXPECT_EQ(e["actor"], "infra/lights_east");
    EXPECT_EQ(e["active"], true);
    EXPECT_EQ(scm::ValueText(answer->Value(std::to_string(id))),  // scmctl's plain line
              scm::LocalDateTime(1795240000.125) +
                  " alarm lamp_fault signal_3: red lamp out (by infra/lights_east) [active]");
  }

  server.Stop();
  scm.Stop();
  loop.join();
}

}  // namespace
}  // namespace autodrive::dashboard
