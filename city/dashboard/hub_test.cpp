#include "city/dashboard/hub.h"

#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "city/dashboard/server.h"

#include "common/error.h"

namespace autodrive::dashboard {
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

struct Sse {
  std::string event;
  json data;
};

/// The SSE messages waiting for `s` (parsed back: the page's view).
std::vector<Sse> Drain(Subscriber& s) {
  std::vector<std::shared_ptr<const std::string>> raw;
  std::vector<Sse> out;
  if (!s.Wait(raw, 0ms)) return out;
  for (const auto& m : raw) {
    Sse e;
    std::size_t pos = 0;
    while (pos < m->size()) {
      const std::size_t end = m->find('\n', pos);
      const std::string line = m->substr(pos, end - pos);
      if (line.starts_with("event: ")) e.event = line.substr(7);
      if (line.starts_with("data: ")) e.data = json::parse(line.substr(6));
      pos = end + 1;
    }
    out.push_back(std::move(e));
  }
  return out;
}

json SpatX(int id, int revision, const std::string& state) {
  return {{"id", id},
          {"name", "x" + std::to_string(id)},
          {"revision", revision},
          {"groups", json::array({{{"id", 1}, {"state", state}}})}};
}

Hub MakeHub(Hub::Options options = {}) {
  return Hub(json{{"city", "town"}, {"heads", json::array()}}, json::array(), true, options);
}

TEST(DashboardHub, ABrowserGetsTheWholeStateFirstThenOnlyChanges) {
  Hub hub = MakeHub();
  hub.SetLamp(3, 1, 1000.0);
  hub.SetSpat(50.0, {SpatX(1, 7, "stop_and_remain")}, 1000.0);
  auto browser = hub.Subscribe();
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].event, "state");
  EXPECT_EQ(got[0].data["city"], "town");
  EXPECT_EQ(got[0].data["heads"]["3"], 1);
  EXPECT_EQ(got[0].data["spat"][0]["revision"], 7);
  EXPECT_EQ(got[0].data["now"], 50.0);
  EXPECT_TRUE(got[0].data["actions_need_token"]);

  hub.SetLamp(3, 1, 1001.0);  // the same lamp again: nothing
  hub.SetLamp(3, 3, 1002.0);
  hub.SetLamp(4, 2, 1003.0);  // a head first seen
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].event, "lamps");
  EXPECT_EQ(got[0].data["heads"]["3"], 3);
  EXPECT_EQ(got[0].data["rx"], 1002.0);
  EXPECT_EQ(got[1].data["heads"]["4"], 2);

  // SPaT: every message goes out (its clock), with only the intersections that changed.
  hub.SetSpat(50.1, {SpatX(1, 7, "stop_and_remain"), SpatX(2, 1, "dark")}, 1004.0);
  hub.SetSpat(50.2, {SpatX(1, 8, "protected_movement_allowed"), SpatX(2, 1, "dark")}, 1005.0);
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  ASSERT_EQ(got[0].data["intersections"].size(), 1u);
  EXPECT_EQ(got[0].data["intersections"][0]["id"], 2);
  ASSERT_EQ(got[1].data["intersections"].size(), 1u);
  EXPECT_EQ(got[1].data["intersections"][0]["revision"], 8);
  EXPECT_EQ(got[1].data["now"], 50.2);

  // A second browser starts from everything so far.
  auto second = hub.Subscribe();
  got = Drain(*second);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].data["heads"]["3"], 3);
  EXPECT_EQ(got[0].data["heads"]["4"], 2);
  EXPECT_EQ(got[0].data["spat"].size(), 2u);
  EXPECT_EQ(hub.counters().subscribers, 2u);
}

TEST(DashboardHub, IntersectionsDevicesAndProcessesGoOutWhenTheyChange) {
  Hub hub = MakeHub();
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  const json a{{"name", "centre"}, {"mode", "auto"}};
  const json b{{"name", "east"}, {"mode", "auto"}};
  hub.SetIntersections({a, b}, 1.0);
  hub.SetIntersections({a, b}, 2.0);
  json a_flash = a;
  a_flash["mode"] = "flash";
  hub.SetIntersections({a_flash, b}, 3.0);
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].data["intersections"].size(), 2u);
  ASSERT_EQ(got[1].data["intersections"].size(), 1u);
  EXPECT_EQ(got[1].data["intersections"][0]["mode"], "flash");

  // A device's report time alone does not make a message; its health does.
  hub.SetDevice({{"id", "signal_1"}, {"health", "ok"}, {"last", 1.0}}, 1.0);
  hub.SetDevice({{"id", "signal_1"}, {"health", "ok"}, {"last", 2.0}}, 2.0);
  hub.SetDevice({{"id", "signal_1"}, {"health", "fault"}, {"last", 3.0}}, 3.0);
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].data["devices"][0]["health"], "fault");
  EXPECT_EQ(hub.State()["devices"][0]["last"], 3.0);

  hub.SetProcesses(json::array({{{"name", "scm"}, {"state", "running"}}}), 1.0);
  hub.SetProcesses(json::array({{{"name", "scm"}, {"state", "running"}}}), 2.0);
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].event, "processes");
}

TEST(DashboardHub, EventsAreKeptOnceAndOnlyActiveAlarmsCanBeAcknowledged) {
  Hub::Options options;
  options.max_events = 3;
  Hub hub = MakeHub(options);
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  hub.AddEvent({{"id", 1}, {"severity", 0}, {"active", false}}, 1.0);
  hub.AddEvent({{"id", 2}, {"severity", 2}, {"active", true}}, 1.0);
  hub.AddEvent({{"id", 2}, {"severity", 2}, {"active", true}}, 1.0);  // latched repeat
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_TRUE(got[1].data["event"]["acked_by"].is_null());

  EXPECT_FALSE(hub.Ack(1, "alice", 10.0));  // information, not an alarm
  EXPECT_FALSE(hub.Ack(9, "alice", 10.0));  // unknown
  EXPECT_TRUE(hub.Ack(2, "alice", 10.0));
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].event, "ack");
  EXPECT_EQ(got[0].data["by"], "alice");
  EXPECT_EQ(hub.State()["events"][1]["acked_by"], "alice");

  for (int id = 3; id <= 6; ++id) hub.AddEvent({{"id", id}, {"severity", 0}}, 1.0);
  const json events = hub.State()["events"];
  ASSERT_EQ(events.size(), 3u);
  EXPECT_EQ(events[0]["id"], 4);
  EXPECT_EQ(events[2]["id"], 6);
}

TEST(DashboardHub, EventsOfTwoSourcesWithOneIdAreBothShownAndTheAlarmIsTheOneAcknowledged) {
  // The SCM numbers its events by its event log, a light host per session: their ids meet.
  Hub hub = MakeHub();
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  hub.AddEvent({{"id", 4}, {"source", "infra/lights"}, {"severity", 1}, {"active", true}}, 1.0);
  hub.AddEvent({{"id", 4}, {"source", "scm"}, {"severity", 2}, {"active", true}}, 1.0);
  hub.AddEvent({{"id", 4}, {"source", "scm"}, {"severity", 2}, {"active", true}}, 1.0);  // again
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].data["event"]["source"], "scm");
  EXPECT_TRUE(hub.Ack(4, "alice", 10.0)) << "the active alarm of id 4, not the warning";
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].data["source"], "scm");
  EXPECT_TRUE(hub.State()["events"][0]["acked_by"].is_null());
  EXPECT_EQ(hub.State()["events"][1]["acked_by"], "alice");
}

/// A lab car (V object) as a district's SCM lists it, observed at `observed` (s).
json Car(const std::string& id, double x, double observed, const std::string& district) {
  return {{"id", id}, {"x", x}, {"observed", observed}, {"district", district}};
}

/// The vehicles of `state` (or of a fleet message) by id: each one's "x" and how many times the
/// id is listed.
std::map<std::string, std::pair<double, int>> ById(const json& vehicles) {
  std::map<std::string, std::pair<double, int>> out;
  for (const json& v : vehicles) {
    auto& [x, n] = out[v.at("id").get<std::string>()];
    x = v.at("x").get<double>();
    ++n;
  }
  return out;
}

TEST(DashboardHub, TheFleetIsTheUnionOfTheDistrictsFleetsACarInTwoOnceByItsNewestReport) {
  Hub hub = MakeHub();
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  hub.SetFleet("uptown", 10.0, json::array({Car("nigel_1", 1.0, 10.0, "uptown")}), 1.0);
  hub.SetFleet("downtown", 10.0, json::array({Car("nigel_2", 2.0, 10.0, "downtown")}), 2.0);
  // Each message carries every car of both districts, not only its district's.
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].event, "fleet");
  EXPECT_EQ(ById(got[1].data["vehicles"]), (std::map<std::string, std::pair<double, int>>{
                                               {"nigel_1", {1.0, 1}}, {"nigel_2", {2.0, 1}}}));

  // nigel_1 crosses into downtown: downtown lists it where it is now, and uptown still lists
  // it where it was last heard there until that is fleet.staleness_s old. Whichever district's
  // message comes last, the car is shown once, at its newest position.
  hub.SetFleet(
      "downtown", 10.5,
      json::array({Car("nigel_2", 2.5, 10.5, "downtown"), Car("nigel_1", 1.5, 10.5, "downtown")}),
      3.0);
  hub.SetFleet("uptown", 10.6, json::array({Car("nigel_1", 1.0, 10.0, "uptown")}), 4.0);
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  for (const Sse& m : got) {
    EXPECT_EQ(ById(m.data["vehicles"]), (std::map<std::string, std::pair<double, int>>{
                                            {"nigel_1", {1.5, 1}}, {"nigel_2", {2.5, 1}}}));
  }
  json state = hub.State()["vehicles"];
  ASSERT_EQ(state.size(), 2u);
  for (const json& v : state) {
    EXPECT_EQ(v["district"], "downtown") << v.dump();  // the report shown is downtown's
  }

  // Uptown drops it (stale there): uptown's empty fleet removes only uptown's cars.
  hub.SetFleet("uptown", 11.1, json::array(), 5.0);
  EXPECT_EQ(ById(hub.State()["vehicles"]), (std::map<std::string, std::pair<double, int>>{
                                               {"nigel_1", {1.5, 1}}, {"nigel_2", {2.5, 1}}}));
  // Downtown's empty fleet empties the page's: no district lists a car any more.
  hub.SetFleet("downtown", 11.2, json::array(), 6.0);
  EXPECT_TRUE(hub.State()["vehicles"].empty());
  // Back in uptown only, as uptown reports it.
  hub.SetFleet("uptown", 12.0, json::array({Car("nigel_1", 0.5, 12.0, "uptown")}), 7.0);
  EXPECT_EQ(ById(hub.State()["vehicles"]),
            (std::map<std::string, std::pair<double, int>>{{"nigel_1", {0.5, 1}}}));
}

TEST(DashboardHub, ACityWithoutDistrictsShowsItsScmsFleetAsItIs) {
  Hub hub = MakeHub();
  const json fleet = json::array({{{"id", "b"}, {"x", 1.0}}, {{"id", "a"}, {"x", 2.0}}});
  hub.SetFleet(5.0, fleet, 1.0);
  EXPECT_EQ(hub.State()["vehicles"], fleet);
  hub.SetFleet(5.1, json::array(), 2.0);
  EXPECT_TRUE(hub.State()["vehicles"].empty());
}

TEST(DashboardHub, TheDistrictsSpatLampsDevicesAndIntersectionsMergeByTheirIds) {
  // Each district's SCM publishes its own intersections, lamps and devices: the page shows all.
  Hub hub = MakeHub();
  hub.SetSpat(50.0, {SpatX(1, 3, "stop_and_remain")}, 1.0);   // uptown's
  hub.SetSpat(50.05, {SpatX(2, 9, "stop_and_remain")}, 1.0);  // downtown's
  hub.SetSpat(50.1, {SpatX(1, 4, "protected_movement_allowed")}, 1.0);
  hub.SetLamp(1, 3, 1.0);
  hub.SetLamp(4, 1, 1.0);
  hub.SetDevice({{"id", "signal_1"}, {"health", "ok"}, {"district", "uptown"}}, 1.0);
  hub.SetDevice({{"id", "signal_4"}, {"health", "ok"}, {"district", "downtown"}}, 1.0);
  hub.SetIntersections({{{"name", "north_t"}, {"district", "uptown"}}}, 1.0);
  hub.SetIntersections({{{"name", "centre"}, {"district", "downtown"}}}, 1.0);
  const json state = hub.State();
  ASSERT_EQ(state["spat"].size(), 2u);
  EXPECT_EQ(state["spat"][0]["revision"], 4);
  EXPECT_EQ(state["spat"][1]["revision"], 9);
  EXPECT_EQ(state["heads"], (json{{"1", 3}, {"4", 1}}));
  EXPECT_EQ(state["devices"].size(), 2u);
  EXPECT_EQ(state["intersections"].size(), 2u);
}

TEST(DashboardHub, EventsOfTwoDistrictsWithOneIdAreBothShownAndEachAcknowledgedInItsDistrict) {
  // Each district's SCM numbers its events by its own event log: their ids meet.
  Hub hub = MakeHub();
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  const auto alarm = [](const std::string& district) {
    return json{
        {"id", 5}, {"source", "scm"}, {"district", district}, {"severity", 2}, {"active", true}};
  };
  hub.AddEvent(alarm("uptown"), 1.0);
  hub.AddEvent(alarm("downtown"), 1.0);
  hub.AddEvent(alarm("downtown"), 1.0);  // latched repeat
  auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].data["event"]["district"], "downtown");
  EXPECT_FALSE(hub.Ack(5, "alice", 10.0, "midtown"));
  EXPECT_TRUE(hub.Ack(5, "alice", 10.0, "downtown"));
  got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].event, "ack");
  EXPECT_EQ(got[0].data["district"], "downtown");
  EXPECT_TRUE(hub.State()["events"][0]["acked_by"].is_null());
  EXPECT_EQ(hub.State()["events"][1]["acked_by"], "alice");
  EXPECT_TRUE(hub.Ack(5, "bob", 11.0, "uptown"));
  EXPECT_EQ(hub.State()["events"][0]["acked_by"], "bob");
}

TEST(DashboardHub, TrafficIsThinnedToItsIntervalAndAlwaysCurrentInTheState) {
  Hub::Options options;
  options.traffic_interval = std::chrono::hours(1);
  Hub hub = MakeHub(options);
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  EXPECT_TRUE(
      hub.SetTraffic(json::array({json::array({"a", 1, 0.5, 0.5, 0.0, 0.3, 0.2, 0.1})}), 1.0));
  // The objects sent are the state's too (they go into the message and back, not copied).
  ASSERT_EQ(hub.State()["objects"].size(), 1u);
  EXPECT_EQ(hub.State()["objects"][0][0], "a");
  EXPECT_FALSE(hub.SetTraffic(json::array(), 2.0));
  const auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].data["objects"].size(), 1u);
  EXPECT_TRUE(hub.State()["objects"].empty());
}

TEST(DashboardHub, ABrowserThatFallsBehindIsDroppedAndTheOthersKeepTheirStream) {
  Hub::Options options;
  options.max_queue_bytes = 4096;
  Hub hub = MakeHub(options);
  auto slow = hub.Subscribe();
  auto fast = hub.Subscribe();
  (void)Drain(*slow);
  for (int i = 0; i < 200; ++i) {
    hub.SetLamp(1, 1 + i % 3, 1.0);
    if (i % 10 == 0) (void)Drain(*fast);
  }
  EXPECT_TRUE(slow->closed());
  std::vector<std::shared_ptr<const std::string>> raw;
  EXPECT_FALSE(slow->Wait(raw, 0ms));  // the stream ends; the browser reconnects
  EXPECT_FALSE(fast->closed());
  EXPECT_EQ(hub.counters().dropped, 1u);
  EXPECT_EQ(hub.counters().subscribers, 1u);
}

TEST(DashboardHub, LampDeviceAndEventChangesWithinTheBatchIntervalGoOutAsOneMessageEach) {
  Hub::Options options;
  options.batch_interval = std::chrono::hours(1);  // only Flush() ends a batch here
  Hub hub = MakeHub(options);
  auto browser = hub.Subscribe();
  (void)Drain(*browser);
  hub.SetLamp(1, 1, 1005.0);
  hub.SetLamp(2, 3, 1001.0);
  hub.SetLamp(1, 2, 1007.0);  // the same head again: its newest lamp
  hub.SetDevice({{"id", "signal_1"}, {"health", "ok"}, {"lamp", 1}, {"last", 1.0}}, 1002.0);
  hub.SetDevice({{"id", "signal_1"}, {"health", "ok"}, {"lamp", 2}, {"last", 2.0}}, 1003.0);
  hub.AddEvent({{"id", 7}, {"severity", 2}, {"active", true}}, 1004.0);
  hub.AddEvent({{"id", 8}, {"severity", 2}, {"active", false}}, 1006.0);
  EXPECT_TRUE(Drain(*browser).empty());
  // A browser that comes now has them in its state already.
  EXPECT_EQ(hub.State()["heads"]["1"], 2);
  hub.Flush();
  const auto got = Drain(*browser);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0].event, "lamps");
  EXPECT_EQ(got[0].data["heads"], (json{{"1", 2}, {"2", 3}}));
  EXPECT_EQ(got[0].data["rx"], 1001.0);  // the oldest: latency is never understated
  EXPECT_EQ(got[1].event, "events");
  ASSERT_EQ(got[1].data["events"].size(), 2u);
  EXPECT_EQ(got[1].data["events"][0]["id"], 7);
  EXPECT_EQ(got[2].event, "devices");
  ASSERT_EQ(got[2].data["devices"].size(), 1u);  // its lamp changed, nothing else
  hub.Flush();
  EXPECT_TRUE(Drain(*browser).empty());
}

TEST(DashboardTokens, AFileOfNamesAndTokensIsCheckedAndMatchedExactly) {
  const Tokens t = Tokens::Parse(
      "# operators\nalice 0123456789abcdef0123\n\nbob   ZZZZZZZZZZZZZZZZ-_ # night shift\n",
      "tokens");
  EXPECT_EQ(t.size(), 2u);
  EXPECT_EQ(t.Find("0123456789abcdef0123"), "alice");
  EXPECT_EQ(t.Find("ZZZZZZZZZZZZZZZZ-_"), "bob");
  EXPECT_FALSE(t.Find("0123456789abcdef012"));
  EXPECT_FALSE(t.Find("0123456789abcdef01234"));
  EXPECT_FALSE(t.Find(""));
  EXPECT_THROW((void)Tokens::Parse("alice short\n", "f"), InputError);
  EXPECT_THROW((void)Tokens::Parse("alice\n", "f"), InputError);
  EXPECT_THROW((void)Tokens::Parse("a b c\n", "f"), InputError);
  EXPECT_THROW((void)Tokens::Parse("a/b 0123456789abcdef\n", "f"), InputError);
  EXPECT_THROW((void)Tokens::Parse("a 0123456789abcdef\nb 0123456789abcdef\n", "f"), InputError);
  EXPECT_THROW((void)Tokens::Parse("a 0123456789abcdef\na 0123456789abcdeg\n", "f"), InputError);
  EXPECT_TRUE(Tokens::Parse("", "f").empty());
}

}  // namespace
}  // namespace autodrive::dashboard
