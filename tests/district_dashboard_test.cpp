// The dashboard of a city of two districts (docs/districts.md, docs/dashboard.md), all as real
// processes: an SCM and a light host per district, each on its own DDS domain, and
// `autodrive-dashboard --city` on the default domain. Read through the dashboard's HTTP API, as
// the page reads it: it holds both districts' intersections with live SPaT, lamps and devices;
// an operator action on an intersection reaches the SCM of that intersection's district (each
// SCM is asked directly, on its own domain), and a configuration reaches both.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config.h"
#include "common/process.h"
#include "tests/scm_processes.h"

// Last: it brings <resolv.h>, whose `_res` macro breaks Eigen's headers included before it.
#include <httplib.h>

namespace autodrive {
namespace {

using nlohmann::json;
using std::chrono::seconds;
using test::Config;
using ::testing::HasSubstr;

constexpr const char* kToken = "district_dashboard_token_0123";

/// `j[key]`, or null when `j` is no object or has no `key` (a state read while the dashboard
/// starts may lack anything).
const json& Field(const json& j, const std::string& key) {
  static const json kNull;
  if (!j.is_object()) return kNull;
  const auto it = j.find(key);
  return it == j.end() ? kNull : *it;
}

/// `j[key]` as text, or "".
std::string Text(const json& j, const std::string& key) {
  const json& v = Field(j, key);
  return v.is_string() ? v.get<std::string>() : std::string();
}

class DistrictDashboard : public test::ScmProcesses {
 protected:
  httplib::Client Http() const {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(150, 0);  // a configuration is checked and applied by two SCMs
    c.set_connection_timeout(10, 0);
    return c;
  }
  /// GET `path`'s JSON, or null.
  json Get(const std::string& path) const {
    const auto res = Http().Get(path);
    if (!res || res->status != 200) return nullptr;
    return json::parse(res->body, nullptr, false);
  }
  /// An operator action, with the token: the dashboard's answer (null when none).
  json Act(const std::string& command, const json& args) const {
    const auto res =
        Http().Post("/api/action", {{"Authorization", std::string("Bearer ") + kToken}},
                    json{{"command", command}, {"args", args}}.dump(), "application/json");
    if (!res) return nullptr;
    return json::parse(res->body, nullptr, false);
  }
  /// Waits up to `timeout` for a state (GET /api/state) that `pred` likes; the last state read.
  json WaitState(const std::function<bool(const json&)>& pred,
                 test::SteadyClock::duration timeout) const {
    const auto end = test::SteadyClock::now() + timeout;
    json state;
    for (;;) {
      state = Get("/api/state");
      if (state.is_object() && pred(state)) return state;
      if (test::SteadyClock::now() >= end) return state;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));  // paces the polls
    }
  }
  /// The intersections of `state`'s map by name: id and district.
  static std::map<std::string, std::pair<std::uint32_t, std::string>> MapIntersections(
      const json& state) {
    std::map<std::string, std::pair<std::uint32_t, std::string>> out;
    for (const json& x : Field(Field(state, "map"), "intersections")) {
      if (!x.is_object()) continue;
      out[Text(x, "name")] = {x.value("id", 0u), Text(x, "district")};
    }
    return out;
  }
  /// The SCM's view of intersection `name` in `state` (I), or null.
  static json Intersection(const json& state, const std::string& name) {
    for (const json& i : Field(state, "intersections")) {
      if (Text(i, "name") == name) return i;
    }
    return nullptr;
  }
  /// The SPaT of intersection `id` in `state` (X), or null.
  static json Spat(const json& state, std::uint32_t id) {
    for (const json& x : Field(state, "spat")) {
      if (x.is_object() && x.value("id", 0u) == id) return x;
    }
    return nullptr;
  }
  /// Whether SPaT `x` has a group that may go.
  static bool AnyGreen(const json& x) {
    for (const json& g : Field(x, "groups")) {
      const std::string s = Text(g, "state");
      if (s == "protected_movement_allowed" || s == "permissive_movement_allowed") return true;
    }
    return false;
  }
  /// Whether every group of SPaT `x` flashes (red or yellow).
  static bool AllFlashing(const json& x) {
    if (Field(x, "groups").empty()) return false;
    for (const json& g : Field(x, "groups")) {
      const std::string s = Text(g, "state");
      if (s != "stop_then_proceed" && s != "caution_conflicting_traffic") return false;
    }
    return true;
  }
  /// The SCM on `domain` (scmctl --json intersections): each intersection's mode, by name.
  std::map<std::string, std::string> ScmModes(std::uint32_t domain) const {
    const test::Output out =
        Scmctl({"--domain", std::to_string(domain), "--json", "intersections"});
    std::map<std::string, std::string> modes;
    std::istringstream lines(out.text);
    for (std::string line; std::getline(lines, line);) {
      const json answer = json::parse(line, nullptr, false);
      if (!answer.is_object() || !answer.contains("values")) continue;
      for (const auto& [name, x] : answer["values"].items()) {
        if (x.is_object()) modes[name] = Text(x, "mode");
      }
    }
    return modes;
  }

  int port_ = 0;
};

/// A short account of a dashboard state, for failure messages.
std::string Summary(const json& state) {
  if (!state.is_object()) return "no state";
  json s = json::object();
  for (const char* key : {"intersections", "spat", "heads", "devices"}) s[key] = Field(state, key);
  json events = json::array();
  for (const json& e : Field(state, "events")) {
    events.push_back(Text(e, "district") + "/" + Text(e, "code"));
  }
  s["events"] = events;
  return s.dump();
}

TEST_F(DistrictDashboard, ShowsEveryDistrictAndSendsEachActionToTheScmOfItsDistrict) {
  const std::uint32_t uptown = Uptown();
  const std::uint32_t downtown = Downtown();
  const std::string city_text = SmallTownInDistricts();
  const std::string city = Write("city.yaml", city_text);
  const auto [up_lights, down_lights] = SmallTownDistrictLights();
  const std::string tokens = Write("tokens", std::string("alice ") + kToken + "\n");
  std::filesystem::permissions(
      tokens, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  const auto common = [&](std::vector<std::string> argv) {
    argv.insert(argv.end(), {"--partition", partition_, "--log-level", "warn"});
    return argv;
  };
  const std::vector<std::string> dashboard = {test::Bin("autodrive-dashboard"),
                                              "--city",
                                              city,
                                              "--listen",
                                              "127.0.0.1:0",
                                              "--token-file",
                                              tokens};

  // On a district's domain, the dashboard is refused, naming why.
  {
    std::vector<std::string> argv = common(dashboard);
    argv.insert(argv.end(), {"--domain", std::to_string(uptown), "--duration", "5"});
    const test::Output refused = test::RunCaptured(argv);
    EXPECT_EQ(refused.code, 1) << refused.text;
    EXPECT_THAT(
        refused.text,
        HasSubstr(fmt::format("district uptown is on DDS domain {}, this program's own", uptown)));
  }

  std::vector<std::unique_ptr<ChildProcess>> processes;
  const auto start = [&](std::vector<std::string> argv) {
    processes.push_back(std::make_unique<ChildProcess>(
        common(std::move(argv)), std::vector<std::string>{test::NoonTimeZone()}));
    return processes.back().get();
  };
  ChildProcess* web = start(dashboard);
  start({test::Bin("autodrive-infra"), "--config", up_lights, "--domain", std::to_string(uptown)});
  start({test::Bin("autodrive-infra"), "--config", down_lights, "--domain",
         std::to_string(downtown)});
  // A configuration an operator sends may name maps under the shipped config/ (the city's own).
  for (const char* district : {"uptown", "downtown"}) {
    start({test::Bin("autodrive-scm"), "--config", city, "--district", district, "--db",
           (dir_ / (std::string(district) + ".db")).string(), "--config-root", Config("config")});
  }

  // The dashboard's one line on stdout: its address.
  const std::optional<std::string> url = web->ReadLine(std::chrono::seconds(120));
  ASSERT_TRUE(url) << "the dashboard printed no address";
  const std::string prefix = "http://127.0.0.1:";
  ASSERT_EQ(url->rfind(prefix, 0), 0u) << *url;
  port_ = std::stoi(url->substr(prefix.size()));

  // The map names each intersection's district, and the districts.
  const json first = WaitState([](const json&) { return true; }, seconds(60));
  ASSERT_TRUE(first.is_object()) << "GET /api/state failed";
  const auto xs = MapIntersections(first);
  ASSERT_TRUE(xs.contains("north_t") && xs.contains("centre")) << Field(first, "map").dump();
  EXPECT_EQ(xs.at("north_t").second, "uptown");
  EXPECT_EQ(xs.at("centre").second, "downtown");
  EXPECT_EQ(Field(Field(first, "map"), "districts"),
            (json::array({{{"name", "uptown"}, {"domain", uptown}},
                          {{"name", "downtown"}, {"domain", downtown}}})));
  const std::uint32_t north_t = xs.at("north_t").first;
  const std::uint32_t centre = xs.at("centre").first;

  // Both districts on the page: each SCM's intersections and SPaT past its start-up (a green),
  // every head's lamp (north_t's on uptown's domain, centre's on downtown's), each district's
  // devices.
  const auto has_device = [](const json& state, const std::string& id,
                             const std::string& district) {
    for (const json& d : Field(state, "devices")) {
      if (Text(d, "id") == id && Text(d, "district") == district) return true;
    }
    return false;
  };
  json state = WaitState(
      [&](const json& s) {
        return Text(Intersection(s, "north_t"), "district") == "uptown" &&
               Text(Intersection(s, "centre"), "district") == "downtown" &&
               AnyGreen(Spat(s, north_t)) && AnyGreen(Spat(s, centre)) &&
               Field(s, "heads").size() == 7 && has_device(s, "signal_1", "uptown") &&
               has_device(s, "signal_4", "downtown");
      },
      seconds(240));
  ASSERT_TRUE(AnyGreen(Spat(state, north_t))) << "no live SPaT of uptown: " << Summary(state);
  ASSERT_TRUE(AnyGreen(Spat(state, centre))) << "no live SPaT of downtown: " << Summary(state);
  EXPECT_EQ(Text(Intersection(state, "north_t"), "district"), "uptown") << Summary(state);
  EXPECT_EQ(Text(Intersection(state, "centre"), "district"), "downtown") << Summary(state);
  EXPECT_EQ(Field(state, "heads").size(), 7u) << Summary(state);
  EXPECT_TRUE(has_device(state, "signal_1", "uptown")) << Summary(state);
  EXPECT_TRUE(has_device(state, "signal_4", "downtown")) << Summary(state);

  // An action on an intersection goes to the SCM of its district (the other does not run it,
  // and would refuse it).
  const json up_answer = Act("mode", {{"intersection", "north_t"}, {"mode", "flash"}});
  EXPECT_EQ(Text(up_answer, "result"), "ok") << up_answer.dump();
  EXPECT_EQ(Text(up_answer, "district"), "uptown") << up_answer.dump();
  const json down_answer =
      Act("mode", {{"intersection", std::to_string(centre)}, {"mode", "flash"}});  // by its id
  EXPECT_EQ(Text(down_answer, "result"), "ok") << down_answer.dump();
  EXPECT_EQ(Text(down_answer, "district"), "downtown") << down_answer.dump();
  const json nowhere = Act("mode", {{"intersection", "nowhere"}, {"mode", "flash"}});
  EXPECT_EQ(Text(nowhere, "result"), "rejected") << nowhere.dump();
  EXPECT_THAT(Text(nowhere, "message"), HasSubstr("no intersection \"nowhere\""));

  // Each SCM, asked on its own domain, runs its own intersection in flash, and only that one.
  EXPECT_EQ(ScmModes(uptown), (std::map<std::string, std::string>{{"north_t", "flash"}}));
  EXPECT_EQ(ScmModes(downtown), (std::map<std::string, std::string>{{"centre", "flash"}}));
  // And the page shows it: the SCMs' answers and their SPaT.
  state = WaitState(
      [&](const json& s) {
        return Text(Intersection(s, "north_t"), "mode") == "flash" &&
               Text(Intersection(s, "centre"), "mode") == "flash" &&
               AllFlashing(Spat(s, north_t)) && AllFlashing(Spat(s, centre));
      },
      seconds(120));
  EXPECT_EQ(Text(Intersection(state, "north_t"), "mode"), "flash") << Summary(state);
  EXPECT_EQ(Text(Intersection(state, "centre"), "mode"), "flash") << Summary(state);
  EXPECT_TRUE(AllFlashing(Spat(state, north_t))) << Summary(state);
  EXPECT_TRUE(AllFlashing(Spat(state, centre))) << Summary(state);

  // The event history holds both SCMs' logs, each event with its district.
  std::set<std::string> history_districts;
  const json history = Get("/api/events?limit=200");
  ASSERT_TRUE(Field(history, "events").is_array()) << history.dump();
  EXPECT_TRUE(Field(history, "unanswered").is_null()) << history.dump();
  for (const json& e : Field(history, "events")) history_districts.insert(Text(e, "district"));
  EXPECT_EQ(history_districts, (std::set<std::string>{"uptown", "downtown"})) << history.dump();

  // A configuration is the whole city's: each district's SCM checks it, then applies its part.
  const json applied = Act("config_apply", {{"yaml", city_text}});
  EXPECT_EQ(Text(applied, "result"), "ok") << applied.dump();
  std::set<std::string> applied_by;
  for (const json& d : Field(applied, "districts")) {
    if (Text(d, "result") == "ok") applied_by.insert(Text(d, "district"));
  }
  EXPECT_EQ(applied_by, (std::set<std::string>{"uptown", "downtown"})) << applied.dump();
  const auto applied_in = [](const json& s, const std::string& district) {
    for (const json& e : Field(s, "events")) {
      if (Text(e, "code") == "config_applied" && Text(e, "district") == district) {
        return true;
      }
    }
    return false;
  };
  state =
      WaitState([&](const json& s) { return applied_in(s, "uptown") && applied_in(s, "downtown"); },
                seconds(120));
  EXPECT_TRUE(applied_in(state, "uptown")) << Summary(state);
  EXPECT_TRUE(applied_in(state, "downtown")) << Summary(state);

  // A configuration one district's SCM refuses is applied by none.
  std::string bad = city_text;
  bad.replace(bad.find("intersections: [centre]"), 23, "intersections: [nowhere]");
  const json refused = Act("config_apply", {{"yaml", bad}});
  EXPECT_EQ(Text(refused, "result"), "rejected") << refused.dump();
  EXPECT_THAT(Text(refused, "message"), HasSubstr("no district applied the configuration"));
}

}  // namespace
}  // namespace autodrive
