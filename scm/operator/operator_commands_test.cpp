// The operator commands, table-driven, in-process on a simulated clock with the real parts: the
// Small Town's runtime, device supervision, an SQLite database in the test's folder, the
// configuration loader, and DDS publishers on the test's own partition.
#include "scm/operator/operator_commands.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>

#include "common/config.h"
#include "common/dds/participant.h"
#include "common/test_support.h"
#include "scm/city_bundle.h"
#include "scm/config_loader.h"

namespace autodrive::scm {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using ::testing::HasSubstr;

/// A ConfigService over the real loader (what the daemon does, minus the swap).
class LoaderService final : public ConfigService {
 public:
  explicit LoaderService(ConfigLoader& loader) : loader_(loader) {}
  void Validate(std::string yaml, std::string label, Responder respond) override {
    loader_.Check(
        std::move(yaml), label, {},
        [respond = std::move(respond)](std::unique_ptr<City> city, std::string error) {
          respond(city ? Reply::Ok("valid: city " + city->config.name) : Reply::Rejected(error));
        });
  }
  void Apply(std::string, std::string, std::string, Responder respond) override {
    respond(Reply::Failed("not in this test"));
  }

 private:
  ConfigLoader& loader_;
};

class OperatorCommandsTest : public ::testing::Test {
 protected:
  OperatorCommandsTest()
      : dir_(std::filesystem::temp_directory_path() /
             fmt::format("scm_commands_{}_{}", ::getpid(),
                         ::testing::UnitTest::GetInstance()->current_test_info()->name())),
        participant_(dds::ParticipantOptions{{}, dir_.filename().string(), {}}),
        writers_(participant_) {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    persistence_ = std::make_unique<Persistence>(Store((dir_ / "scm.db").string()), nullptr);
    bundle_ = std::make_unique<CityBundle>(
        std::make_unique<City>(LoadCity(test::SourceDir() / "config/cities/small_town.yaml")),
        participant_, ClockKind::kWall, writers_, std::vector<IntersectionStateRecord>{}, 1);
    bundle_->Start(now_);
    publishers_ = std::make_unique<ScmPublishers>(participant_, "small_town", 42);
    publishers_->Reset(*bundle_->runtime, "small_town");
    loader_ = std::make_unique<ConfigLoader>(
        participant_, ClockKind::kWall, writers_, persistence_->store(),
        MapResolution{test::SourceDir() / "config/cities", test::SourceDir() / "config"}, "",
        nullptr);
    service_ = std::make_unique<LoaderService>(*loader_);
    control_ = std::make_unique<ControlPlane>(ControlPlaneParams{});
  }
  ~OperatorCommandsTest() override {
    loader_.reset();
    std::filesystem::remove_all(dir_);
  }

  /// Runs `command` now; waits for a deferred answer (running completions) if there is one.
  Reply Run(const std::string& name, std::map<std::string, std::string> args = {}) {
    OperatorCommand cmd;
    cmd.client = cmd.actor = "test/client";
    cmd.request_id = ++request_id_;
    cmd.spec = FindCommand(name);
    cmd.name = name;
    cmd.args = std::move(args);
    cmd.intersection = cmd.Arg("intersection");
    CommandContext ctx{*bundle_->runtime,
                       *bundle_->supervisor,
                       *publishers_,
                       *bundle_->lights,
                       *bundle_->fleet,
                       *persistence_,
                       *service_,
                       *control_,
                       figures_,
                       events_,
                       DayClock::At(std::chrono::hours(12))};
    std::optional<Reply> later;
    auto reply = RunOperatorCommand(cmd, now_, ctx, [&](Reply r) { later = std::move(r); });
    if (reply) return *reply;
    // The loader's thread reads and builds a whole city: give it a generous deadline (the
    // machine may be loaded), polling its completions.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!later && std::chrono::steady_clock::now() < deadline) {
      persistence_->Flush();
      persistence_->RunCompletions();
      loader_->RunCompletions();
      if (!later) std::this_thread::sleep_for(milliseconds(1));
    }
    EXPECT_TRUE(later) << name << " never answered";
    return later.value_or(Reply::Failed("no answer"));
  }
  /// Lets the city run for `d` (every light reporting what it is told).
  void RunFor(Duration d) {
    const MonoTime end = now_.mono + d;
    while (now_.mono < end) {
      now_.mono += milliseconds(20);
      now_.wire += milliseconds(20);
      for (std::size_t h = 0; h < bundle_->runtime->heads().size(); ++h) {
        DeviceReportView r;
        r.device_id = names_.emplace_back(bundle_->runtime->heads()[h].name);
        r.city = "small_town";
        r.host = "infra/test";
        r.displayed = bundle_->runtime->AspectOfHead(h);
        bundle_->supervisor->Report(r, now_.mono, *bundle_->runtime, events_);
      }
      bundle_->supervisor->Check(now_.mono, bundle_->lights->sent(), *bundle_->runtime, events_);
      bundle_->runtime->Step(now_, DayClock::At(std::chrono::hours(12)), nullptr, events_);
      bundle_->lights->Sync(*bundle_->runtime, *bundle_->supervisor, now_.mono);
      names_.clear();
    }
  }
  const IntersectionController& Controller(const std::string& name) {
    return *bundle_->runtime->intersections()[*bundle_->runtime->Find(name)].controller;
  }

  std::filesystem::path dir_;
  dds::Participant participant_;
  SignalCommandWriters writers_;
  ClockReading now_{MonoFromSeconds(1000), TimeFromSeconds(1'795'000'000), 0};
  std::unique_ptr<Persistence> persistence_;
  std::unique_ptr<CityBundle> bundle_;
  std::unique_ptr<ScmPublishers> publishers_;
  std::unique_ptr<ConfigLoader> loader_;
  std::unique_ptr<LoaderService> service_;
  std::unique_ptr<ControlPlane> control_;
  DaemonFigures figures_;
  EventRecorder events_;
  std::deque<std::string> names_;
  std::uint64_t request_id_ = 0;
};

/// The arguments of a configuration command for `yaml`, with the length and hash a client sends.
std::map<std::string, std::string> ConfigArgs(const std::string& yaml, std::string path = "") {
  std::map<std::string, std::string> args{{"yaml", yaml},
                                          {"yaml_bytes", std::to_string(yaml.size())},
                                          {"yaml_hash", ContentHash(yaml)}};
  if (!path.empty()) args["path"] = std::move(path);
  return args;
}

TEST_F(OperatorCommandsTest, EachCommandAnswersAsTheTableSays) {
  RunFor(seconds(13));  // through the start-up sequence (flash 3 s, all red 7 s), into the plan
  for (int i = 0; i < 7; ++i) {
    persistence_->AppendEvent(EventRecord{0, now_.wire, Severity::kInfo, "scm", "test_event",
                                          "event " + std::to_string(i), IntersectionId(0), "",
                                          "scm", false});
  }
  struct Case {
    std::string command;
    std::map<std::string, std::string> args;
    ReplyCode code;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"status", {}, ReplyCode::kOk, "city small_town: 2 signalised intersections, 7 lights"},
      {"intersections", {}, ReplyCode::kOk, "2 signalised intersections"},
      {"show", {{"intersection", "centre"}}, ReplyCode::kOk, "centre: id="},
      {"show",
       {{"intersection", "nowhere"}},
       ReplyCode::kInvalid,
       "unknown intersection \"nowhere\" (signalised: "},
      {"mode",
       {{"intersection", "centre"}, {"mode", "sideways"}},
       ReplyCode::kInvalid,
       "unknown mode \"sideways\""},
      {"advance", {{"intersection", "centre"}}, ReplyCode::kRejected, "advance needs manual mode"},
      {"mode",
       {{"intersection", "centre"}, {"mode", "manual"}},
       ReplyCode::kOk,
       "centre mode manual"},
      {"advance", {{"intersection", "centre"}}, ReplyCode::kOk, "advancing"},
      {"plan",
       {{"intersection", "north_t"}, {"plan", "evening"}},
       ReplyCode::kOk,
       "north_t runs plan evening from the next safe point"},
      {"plan",
       {{"intersection", "north_t"}, {"plan", "nope"}},
       ReplyCode::kInvalid,
       "north_t has no plan \"nope\""},
      {"reset",
       {{"intersection", "centre"}},
       ReplyCode::kRejected,
       "centre is not in fail-safe flash; nothing to reset"},
      // Phase controls: set, shown, taken off; bad arguments named.
      {"phase_control",
       {{"intersection", "north_t"}, {"control", "hold"}, {"phase", "2"}, {"for_s", "30"}},
       ReplyCode::kOk,
       "north_t hold phase 2 of plan"},
      {"show", {{"intersection", "north_t"}}, ReplyCode::kOk, "north_t: id="},
      {"phase_control",
       {{"intersection", "north_t"}, {"control", "hold"}, {"phase", "2"}, {"off", "true"}},
       ReplyCode::kOk,
       "north_t hold off phase 2 of plan"},
      {"phase_control",
       {{"intersection", "north_t"}, {"control", "hold"}, {"phase", "2"}, {"off", "true"}},
       ReplyCode::kRejected,
       "north_t has no hold on phase 2 of plan"},
      {"phase_control",
       {{"intersection", "centre"}, {"control", "stop"}, {"phase", "1"}, {"for_s", "5"}},
       ReplyCode::kInvalid,
       "unknown phase control \"stop\" (omit, ped_omit, hold, force_off, call, ped_call)"},
      {"phase_control",
       {{"intersection", "centre"}, {"control", "omit"}, {"phase", "x"}, {"for_s", "5"}},
       ReplyCode::kInvalid,
       "phase must be a phase number (1, 2, ...), got \"x\""},
      {"phase_control",
       {{"intersection", "centre"}, {"control", "omit"}, {"phase", "1"}, {"for_s", "1e9"}},
       ReplyCode::kInvalid,
       "for_s must be the control's duration in seconds, more than 0 and at most 86400"},
      {"phase_control",
       {{"intersection", "centre"}, {"control", "force-off"}, {"phase", "9"}, {"for_s", "5"}},
       ReplyCode::kRejected,
       "there is no phase 9"},
      {"events", {{"limit", "0"}}, ReplyCode::kInvalid, "limit must be a number in 1..10000"},
      {"hires", {{"intersection", "centre"}}, ReplyCode::kInvalid, "hires needs since"},
      {"hires",
       {{"intersection", "centre"}, {"since", "yesterday"}},
       ReplyCode::kInvalid,
       "since must be seconds since the epoch, got \"yesterday\""},
      {"hires",
       {{"intersection", "centre"}, {"since", "100"}, {"until", "50"}},
       ReplyCode::kInvalid,
       "until is before since"},
      {"hires",
       {{"intersection", "centre"}, {"since", "100"}, {"limit", "100001"}},
       ReplyCode::kInvalid,
       "limit must be a number in 1..100000"},
      {"hires", {{"intersection", "nowhere"}, {"since", "100"}}, ReplyCode::kInvalid, "nowhere"},
      {"events", {{"limit", "5"}}, ReplyCode::kOk, "5 events"},
      {"config_validate", ConfigArgs("name: x\n"), ReplyCode::kRejected, "map"},
      {"config_validate", ConfigArgs("name: x\nmap: /etc/passwd\nintersections: []\n", "evil.yaml"),
       ReplyCode::kRejected, "is outside the SCM's configuration root"},
      {"config_validate",
       {{"yaml", "name: x\n"}, {"yaml_bytes", "9999"}, {"yaml_hash", ContentHash("name: x\n")}},
       ReplyCode::kInvalid,
       "the configuration arrived with 8 bytes but was sent with 9999"},
      // Length and hash are required: a client that leaves them out could have a text cut at a
      // NUL byte applied.
      {"config_validate",
       {{"yaml", "name: x\n"}},
       ReplyCode::kInvalid,
       "config_validate needs yaml_bytes (the text's length in bytes) and yaml_hash"},
      {"config_apply",
       {{"yaml", "name: x\n"}, {"yaml_bytes", "8"}},
       ReplyCode::kInvalid,
       "config_apply needs yaml_bytes"},
      {"config_validate",
       {{"yaml", "name: x\n"}, {"yaml_bytes", "8"}, {"yaml_hash", "0123456789abcdef"}},
       ReplyCode::kInvalid,
       "not the 0123456789abcdef it was sent with"},
      {"config_validate",
       ConfigArgs(config::ReadFile(test::SourceDir() / "config/cities/small_town.yaml"),
                  (test::SourceDir() / "config/cities/small_town.yaml").string()),
       ReplyCode::kOk, "valid: city small_town"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.command);
    const Reply r = Run(c.command, c.args);
    EXPECT_EQ(r.code, c.code) << r.message;
    EXPECT_THAT(r.message, HasSubstr(c.says));
  }
  EXPECT_EQ(Controller("centre").requested_mode(), Mode::kManual);
  EXPECT_TRUE(Controller("north_t").operator_plan().has_value());
  // State changes were logged with who, and persisted.
  EXPECT_EQ(events_.WithCode("operator_mode").size(), 1u);
  EXPECT_EQ(events_.WithCode("operator_mode")[0].actor, "test/client");
  EXPECT_EQ(events_.WithCode("operator_phase_control").size(), 2u) << "set and taken off";
  persistence_->Flush();
  const auto states = persistence_->store().LoadIntersectionStates();
  ASSERT_EQ(states.size(), 2u);
}

TEST_F(OperatorCommandsTest, StatusAndShowCountTheBackgroundTrafficPerApproach) {
  RunFor(seconds(1));
  const maps::Map& map = bundle_->city().map;
  const maps::Intersection& centre =
      *std::ranges::find(map.intersections, "centre", &maps::Intersection::name);
  ASSERT_EQ(centre.name, "centre");
  // Two SUMO cars on the centre's east approach (one waiting, one entering the box), one on
  // its north approach and one leaving it westwards.
  const maps::Lane& east = map.lane(centre.approaches.at(0).ingress.at(0));
  const maps::Lane& north = map.lane(centre.approaches.at(1).ingress.at(0));
  const maps::Lane& leaving = map.lane(centre.approaches.at(2).egress.at(0));
  const maps::Movement& turning = map.movement(east.movements_out.at(0));
  const std::vector<TrafficObservation> cars = {
      {"a", east.name, east.centreline[east.centreline.size() - 5], 0.25},
      {"b", turning.name, turning.path[3], 0.25},
      {"c", north.name, north.centreline[10], 0.25},
      {"d", leaving.name, leaving.centreline[10], 0.25},
  };
  ASSERT_EQ(bundle_->fleet->ObserveTraffic(now_.wire, cars).recorded, 4u);
  // Typed values: a count is a number, an approach an object (and its line for people).
  const auto approach = [](std::string side, int lab, int background) {
    return nlohmann::json{{"approach", side},
                          {"lab", lab},
                          {"background", background},
                          {"text", fmt::format("{} lab, {} background vehicles", lab, background)}};
  };
  EXPECT_EQ(Run("status").Value("background_vehicles"), 4);
  const Reply show = Run("show", {{"intersection", "centre"}});
  EXPECT_EQ(show.Value("approach east"), approach("east", 0, 2));
  EXPECT_EQ(show.Value("approach north"), approach("north", 0, 1));
  EXPECT_EQ(show.Value("approach west"), approach("west", 0, 0));
  EXPECT_EQ(show.Value("approach south"), approach("south", 0, 0));
  EXPECT_EQ(ValueText(show.Value("approach east")), "0 lab, 2 background vehicles");
  // Not refreshed: stale after the fleet's staleness (1 s).
  RunFor(milliseconds(1100));
  EXPECT_EQ(Run("status").Value("background_vehicles"), 0);
  EXPECT_EQ(Run("show", {{"intersection", "centre"}}).Value("approach east"),
            approach("east", 0, 0));
}

// `show X --intergreen`: the inputs, and an entry per pair of conflicting groups with its
// figures (scm/core/intergreen.h); none without the flag.
TEST_F(OperatorCommandsTest, ShowWithIntergreenGivesTheMatrixAndItsInputs) {
  EXPECT_TRUE(Run("show", {{"intersection", "north_t"}}).Value("intergreen inputs").is_null());
  const Reply show = Run("show", {{"intersection", "north_t"}, {"intergreen", "true"}});
  ASSERT_EQ(show.code, ReplyCode::kOk);
  const nlohmann::json inputs = show.Value("intergreen inputs");
  EXPECT_EQ(inputs.value("entering_speed_mps", 0.0), 0.26);
  EXPECT_EQ(inputs.value("conflict_reach_m", 0.0), 0.15);
  const IntersectionModel& x = bundle_->city().intersections[*bundle_->runtime->Find("north_t")];
  std::size_t entries = 0;
  for (std::size_t a = 0; a < x.groups.size(); ++a) {
    for (std::size_t b = 0; b < x.groups.size(); ++b) {
      const nlohmann::json e = show.Value(
          fmt::format("intergreen {} > {}", x.groups[a].id.value(), x.groups[b].id.value()));
      EXPECT_EQ(e.is_null(), a == b || !x.conflicts[a][b]) << a << " " << b;
      if (e.is_null()) continue;
      ++entries;
      EXPECT_GT(e.value("intergreen_s", 0.0), 0.0);
      // RiLSA's figure with the city's t_cross (3 s, the yellow) beside ITE's, which has none.
      EXPECT_GE(e.value("ite_s", 0.0) + 3.0, e.value("intergreen_s", 0.0)) << e.dump();
      EXPECT_EQ(e.value("vehicle", ""), "nigel");
      EXPECT_NE(ValueText(e).find(" s = 3.0 + ("), std::string::npos) << e.dump();
    }
  }
  EXPECT_GT(entries, 0u);
}

TEST_F(OperatorCommandsTest, AResetClearsTheLatchAndAsksOnlyThatIntersectionsMonitorToReset) {
  RunFor(seconds(8));
  const std::size_t centre = *bundle_->runtime->Find("centre");
  const std::size_t north = *bundle_->runtime->Find("north_t");
  // Both latched by their infrastructure monitors.
  for (const std::string x : {"centre", "north_t"}) {
    DeviceReportView m;
    const std::string id = "mmu_" + x;
    m.device_id = id;
    m.city = "small_town";
    m.host = "infra/test";
    m.health = DeviceHealth::kFault;
    bundle_->supervisor->Report(m, now_.mono, *bundle_->runtime, events_);
  }
  ASSERT_TRUE(Controller("centre").latched());
  ASSERT_TRUE(Controller("north_t").latched());
  const Reply r = Run("reset", {{"intersection", "north_t"}});
  EXPECT_EQ(r.code, ReplyCode::kOk) << r.message;
  EXPECT_FALSE(Controller("north_t").latched());
  EXPECT_TRUE(Controller("centre").latched()) << "a reset reaches only what it names";
  const auto resets = events_.WithCode("failsafe_reset");
  ASSERT_EQ(resets.size(), 1u);
  EXPECT_THAT(resets[0].message, HasSubstr("infrastructure monitor reset (command 1)"));
  (void)centre;
  (void)north;
}

TEST_F(OperatorCommandsTest, ARefusedResetChangesNothing) {
  RunFor(seconds(8));
  // signal_5 (centre) goes silent: lost, and centre latches.
  const MonoTime end = now_.mono + seconds(1);
  while (now_.mono < end) {
    now_.mono += milliseconds(20);
    for (std::size_t h = 0; h < bundle_->runtime->heads().size(); ++h) {
      if (bundle_->runtime->heads()[h].id.value() == 5) continue;
      DeviceReportView rep;
      rep.device_id = names_.emplace_back(bundle_->runtime->heads()[h].name);
      rep.city = "small_town";
      rep.host = "infra/test";
      rep.displayed = bundle_->runtime->AspectOfHead(h);
      bundle_->supervisor->Report(rep, now_.mono, *bundle_->runtime, events_);
    }
    bundle_->supervisor->Check(now_.mono, bundle_->lights->sent(), *bundle_->runtime, events_);
  }
  ASSERT_TRUE(Controller("centre").latched());
  const Reply r = Run("reset", {{"intersection", "centre"}});
  EXPECT_EQ(r.code, ReplyCode::kRejected);
  EXPECT_THAT(r.message, HasSubstr("signal_5 is still lost; reset refused"));
  EXPECT_TRUE(Controller("centre").latched());
  EXPECT_TRUE(events_.WithCode("failsafe_reset").empty());
}

/// `intersections`' value written directly, against a JSON object of the same summary.
TEST(IntersectionValue, IsWhatAJsonObjectOfTheSummaryIs) {
  IntersectionSummary s;
  s.id = IntersectionId(3);
  s.mode = Mode::kFlash;
  s.requested = Mode::kAuto;
  s.plan = "day";
  s.stage = Stage::kFlash;
  for (const std::optional<std::string>& latched :
       {std::optional<std::string>(), std::optional<std::string>("conflict: 1 and 3 \"green\""),
        std::optional<std::string>("detail \xff\n")}) {
    for (const bool by_operator : {false, true}) {
      s.latched = latched;
      s.plan_by_operator = by_operator;
      s.pending_plan = by_operator ? std::nullopt : std::optional<std::string>("evening");
      SCOPED_TRACE(Describe(s));
      const nlohmann::json reference{
          {"id", 3},
          {"mode", "flash"},
          {"requested", "auto"},
          {"plan", "day"},
          {"plan_by", by_operator ? "operator" : "schedule"},
          {"stage", "flash"},
          {"latched", latched ? nlohmann::json(*latched) : nlohmann::json()},
          {"pending_plan", by_operator ? nlohmann::json() : nlohmann::json("evening")},
          {"text", Describe(s)}};
      const nlohmann::json written = IntersectionValue(s).Parse();
      ASSERT_FALSE(written.is_discarded()) << IntersectionValue(s).json_text();
      // Text that is not UTF-8 is repaired the same way by both.
      EXPECT_EQ(written, nlohmann::json::parse(reference.dump(
                             -1, ' ', false, nlohmann::json::error_handler_t::replace)));
      EXPECT_EQ(ValueText(IntersectionValue(s)), written["text"]);
    }
  }
}

TEST_F(OperatorCommandsTest, HiresAnswersOneIntersectionsRecordsInTheWindowInTimeOrder) {
  const Time t0 = TimeFromSeconds(1795240000.0);
  const IntersectionId centre = bundle_->runtime->city().Find("centre")->id;
  const IntersectionId north = bundle_->runtime->city().Find("north_t")->id;
  persistence_->AppendHires({{centre, t0 + milliseconds(100), hires::kPhaseBeginGreen, 1},
                             {north, t0 + milliseconds(150), hires::kPhaseBeginGreen, 1},
                             {centre, t0 + seconds(8), hires::kPhaseBeginYellow, 1},
                             {centre, t0 + seconds(8), hires::kPhaseGreenTermination, 1},
                             {centre, t0 + seconds(20), hires::kPhaseInactive, 1}});
  const Reply r = Run(
      "hires", {{"intersection", "centre"}, {"since", "1795240000.1"}, {"until", "1795240020"}});
  ASSERT_EQ(r.code, ReplyCode::kOk) << r.message;
  EXPECT_EQ(r.message, "centre: 3 records");
  const nlohmann::json rows = r.Value("records");
  EXPECT_EQ(rows, nlohmann::json::parse(
                      "[[1795240000100, 1, 1], [1795240008000, 8, 1], [1795240008000, 7, 1]]"))
      << "centre's only, until excluded, in time then append order";
  const Reply one = Run("hires", {{"intersection", "centre"},
                                  {"since", "1795240000"},
                                  {"until", "1795240100"},
                                  {"limit", "1"}});
  EXPECT_EQ(one.Value("records").size(), 1u);
}

TEST_F(OperatorCommandsTest, IntersectionsAndEventsAnswerTypedFields) {
  RunFor(seconds(8));
  persistence_->AppendEvent(EventRecord{0, TimeFromSeconds(1795240000.5), Severity::kAlarm,
                                        "infra/lights", "lamp_fault", "signal_3: red lamp out",
                                        IntersectionId(2), "signal_3", "infra/lights", true});
  const Reply xs = Run("intersections");
  ASSERT_EQ(xs.values.size(), 2u);
  const nlohmann::json centre = xs.Value("centre");
  EXPECT_EQ(centre["mode"], ToString(Controller("centre").effective_mode()));
  EXPECT_EQ(centre["requested"], ToString(Controller("centre").requested_mode()));
  EXPECT_EQ(centre["stage"], ToString(Controller("centre").stage()));
  EXPECT_EQ(centre["plan_by"], "schedule");
  EXPECT_TRUE(centre["latched"].is_null());
  EXPECT_EQ(centre["text"], bundle_->runtime->Describe(*bundle_->runtime->Find("centre")));
  const Reply events = Run("events", {{"limit", "100"}});
  const auto it = std::ranges::find_if(events.values, [](const auto& v) {
    return v.second.Parse().value("code", "") == "lamp_fault";
  });
  ASSERT_NE(it, events.values.end());
  const nlohmann::json e = it->second.Parse();
  EXPECT_EQ(e["id"], std::stoll(it->first));
  EXPECT_EQ(e["stamp"], 1795240000.5);
  EXPECT_EQ(e["severity"], "alarm");
  EXPECT_EQ(e["source"], "infra/lights");
  EXPECT_EQ(e["message"], "signal_3: red lamp out");
  EXPECT_EQ(e["intersection"], 2);
  EXPECT_EQ(e["device"], "signal_3");
  EXPECT_EQ(e["actor"], "infra/lights");
  EXPECT_EQ(e["active"], true);
  EXPECT_EQ(ValueText(it->second), LocalDateTime(1795240000.5) +
                                       " alarm lamp_fault signal_3: red lamp out (by "
                                       "infra/lights) [active]");
}

}  // namespace
}  // namespace autodrive::scm
