#include "scenarios/report_html.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "scenarios/internal/report_assets.h"
#include "scenarios/internal/report_data.h"
#include "scenarios/metrics.h"

#include "common/config.h"
#include "common/test_support.h"

namespace autodrive::scenarios {
namespace {

namespace fs = std::filesystem;
using internal::LampBand;
using internal::LampBands;
using nlohmann::json;

// ---- Lamp bands ----

TEST(LampBands, SteadyAspectsAreBandsToTheNextChangeAndTheLastToTheEnd) {
  const auto bands = LampBands({{1.0, 1}, {11.0, 3}, {21.0, 2}, {24.0, 1}}, 30.0);
  EXPECT_EQ(bands, (std::vector<LampBand>{{1, 11, 1}, {11, 21, 3}, {21, 24, 2}, {24, 30, 1}}));
}

TEST(LampBands, AlternatingRedAndOffEveryHalfSecondIsOneFlashingRedBand) {
  std::vector<std::pair<double, int>> changes{{0.0, 3}, {5.0, 2}, {8.0, 1}};
  // Red from 8 s, flashing red from 10 s (the state alternates 0 and 1 every 0.5 s; the log
  // has changes only), steady red again from 13.5 s, green from 20 s.
  for (int i = 0; i < 8; ++i) changes.emplace_back(10.0 + 0.5 * i, i % 2 == 0 ? 0 : 1);
  changes.emplace_back(20.0, 3);
  const auto bands = LampBands(changes, 25.0);
  EXPECT_EQ(bands,
            (std::vector<LampBand>{
                {0, 5, 3}, {5, 8, 2}, {8, 10, 1}, {10, 13.5, 4}, {13.5, 20, 1}, {20, 25, 3}}));
}

TEST(LampBands, FlashingYellowIsItsOwnAspect) {
  std::vector<std::pair<double, int>> changes;
  for (int i = 0; i < 10; ++i) changes.emplace_back(0.5 * i, i % 2 == 0 ? 2 : 0);
  const auto bands = LampBands(changes, 5.0);
  ASSERT_EQ(bands.size(), 1u);
  EXPECT_EQ(bands[0], (LampBand{0, 5, 5}));
}

TEST(LampBands, AShortDarkGlitchBetweenLongRedsIsNotAFlash) {
  const auto bands = LampBands({{0.0, 1}, {10.0, 0}, {10.2, 1}, {30.0, 3}}, 40.0);
  EXPECT_EQ(bands, (std::vector<LampBand>{{0, 10, 1}, {10, 10.2, 0}, {10.2, 30, 1}, {30, 40, 3}}));
}

TEST(LampBands, AlternationSlowerThanTheFlashLimitStaysSteady) {
  std::vector<std::pair<double, int>> changes;
  for (int i = 0; i < 6; ++i) changes.emplace_back(2.0 * i, i % 2 == 0 ? 1 : 0);
  const auto bands = LampBands(changes, 12.0);
  ASSERT_EQ(bands.size(), 6u);
  for (const LampBand& b : bands) EXPECT_TRUE(b.aspect == 0 || b.aspect == 1);
}

TEST(LampBands, NothingBeforeTheFirstChange) {
  const auto bands = LampBands({{3.0, 1}}, 10.0);
  EXPECT_EQ(bands, (std::vector<LampBand>{{3, 10, 1}}));
  EXPECT_TRUE(LampBands({}, 10.0).empty());
}

// ---- A run folder made by hand ----

// One car driving east along y = 0 from x = 0 at 0.25 m/s, through a signalised stop line at
// x = 2 (head 3, red), with a route along the same line.
class ReportRun : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(dir_.path() / "logs");
    RunWorld world;
    RunWorld::Car car;
    car.name = "nigel_1";
    car.route = {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {4, 0}};
    world.cars.push_back(car);
    world.statics.push_back({"obstacle", "0", Rectangle({3.5, 0.5}, 0, 0.1, 0.1)});
    world.stop_lines.push_back(
        {"west:W>E:0", "centre", "signal", {3}, {2, 0.15}, {2, -0.15}, {1, 0}});
    world.stop_lines.push_back(
        {"east:E>W:0", "centre", "signal", {4}, {2.4, -0.15}, {2.4, 0.15}, {-1, 0}});
    world.lanes.push_back({"west:W>E:0", 0.3, {{0, 0}, {2, 0}}});
    world.lanes.push_back({"east:W>E:0", 0.3, {{2, 0}, {4, 0}}});
    world.end_s = 16;
    Write("logs/world.json", world.ToJson().dump());
    std::string truth = "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n";
    for (int i = 0; i <= 1600; ++i) {
      const double t = 0.01 * i;
      truth += fmt::format("{:.6f},nigel_1,{:.6f},0.000000,0.000000,0.250000,0,0\n", t, 0.25 * t);
    }
    Write("logs/ground_truth.csv", truth);
    Write("logs/lamps.csv", "t_s,head,state\n0.0,3,3\n0.0,4,1\n5.0,3,2\n8.0,3,1\n");
    Write(
        "logs/scenario_events.jsonl",
        R"({"t_s":2.0,"at_s":2.0,"action":"mode","intersection":"centre","mode":"flash"})"
        "\n"
        R"({"t_s":3.0,"at_s":3.0,"action":"place","obstacle":"box"})"
        "\n"
        R"({"t_s":4.0,"at_s":4.0,"action":"lamp","head":2,"lamp":"red","fault":"burnt_out"})"
        "\n"
        R"({"t_s":5.0,"at_s":5.0,"action":"surge","from":"a","per_hour":600,"count":5,"type":"bus"})"
        "\n");
    Write(
        "logs/spat.jsonl",
        R"({"t_s":0.1,"intersection":7,"name":"centre","status":32,"revision":1,"plan":"day","groups":[]})"
        "\n"
        R"({"t_s":0.2,"intersection":7,"name":"centre","status":32,"revision":1,"plan":"day","groups":[]})"
        "\n"
        R"({"t_s":2.1,"intersection":7,"name":"centre","status":4,"revision":2,"plan":"day","groups":[]})"
        "\n");
    Write(
        "logs/events.jsonl",
        R"({"t_s":2.1,"severity":3,"source":"scm","code":"</script><b>flash</b>","message":"m","intersection":7,"device":"","active":true})"
        "\n");
    Write(
        "logs/requests.jsonl",
        R"({"t_s":3.0,"kind":"request","vehicle":"nigel_1","request_id":1,"type":2,"role":2,"intersection":7,"in_lane":5,"out_lane":6})"
        "\n"
        R"({"t_s":3.1,"kind":"status","vehicle":"nigel_1","request_id":1,"intersection":7,"status":3,"group":0,"reason":"flashing"})"
        "\n");
    report_ = {{"scenario",
                {{"name", "hand_made"},
                 {"description", "a </script><script>window.bad=1</script> <!-- description"},
                 {"text", "name: hand_made\n"}}},
               {"seed", 1},
               {"city", "test_town"},
               {"end", {{"reason", "time_limit"}, {"t_s", 16.0}, {"failure", ""}}},
               {"passed", false},
               {"expect", json::array({{{"metric", "red_light_violations"},
                                        {"expect", "== 0"},
                                        {"value", 1},
                                        {"held", false}}})},
               {"metrics",
                {{"run", {{"red_light_violations", 1}}},
                 {"vehicles",
                  {{"nigel_1",
                    {{"red_light_violations", json::array({{{"t_s", 9.0},
                                                            {"intersection", "centre"},
                                                            {"lane", "west:W>E:0"},
                                                            {"head", 3},
                                                            {"speed_mps", 0.25}}})},
                     {"collisions", json::array()},
                     {"time_to_goal_s", nullptr}}}}}}}};
  }

  void Write(const std::string& name, const std::string& text) const {
    config::WriteFile(dir_.path() / name, text);
  }

  // The page's data, read back from the page as the browser would.
  static json DataOf(const std::string& page) {
    const std::string open = "<script type=\"application/json\" id=\"page-data\">";
    const auto from = page.find(open);
    EXPECT_NE(from, std::string::npos);
    const auto to = page.find("</script>", from);
    return json::parse(page.substr(from + open.size(), to - from - open.size()));
  }

  test::TempDir dir_{"scenarios_report_html"};
  json report_;
};

std::size_t Count(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST_F(ReportRun, ThePageCarriesItsDataWithNoWayOutOfItsScriptElement) {
  const std::string page = ReportHtml(report_, dir_.path());
  // Four scripts (data, uPlot, common, report): a "</script" in a description or an event code
  // does not end the data early.
  EXPECT_EQ(Count(page, "</script>"), 4u);
  EXPECT_EQ(Count(page, "<!--"), 0u);
  const json data = DataOf(page);
  EXPECT_EQ(data["report"]["scenario"]["description"],
            report_["scenario"]["description"].get<std::string>());
  EXPECT_NE(page.find("<title>hand_made — FAILED</title>"), std::string::npos);
}

TEST_F(ReportRun, ThePageLoadsNothing) {
  const std::string page = ReportHtml(report_, dir_.path());
  EXPECT_NE(page.find("<link rel=\"icon\" href=\"data:,\">"), std::string::npos);
  EXPECT_NE(page.find("default-src 'none'"), std::string::npos);
  // The only URL is in uPlot's licence banner (a comment), and no element has a source.
  EXPECT_EQ(Count(page, "http://") + Count(page, "https://"), 1u);
  EXPECT_NE(page.find("/*! https://github.com/leeoniya/uPlot (v1.6.32) */"), std::string::npos);
  EXPECT_EQ(Count(page, " src="), 0u);
  EXPECT_EQ(Count(page, "href="), 1u);  // the icon's data:
  EXPECT_EQ(Count(page, "fetch("), 0u);
  EXPECT_EQ(Count(page, "XMLHttpRequest"), 0u);
}

TEST_F(ReportRun, TheVendoredUplotIsEmbeddedByteForByte) {
  const auto& a = internal::ReportAssets();
  EXPECT_EQ(a.uplot_js, config::ReadFile(test::SourceDir() /
                                         "scenarios/vendor/uplot-1.6.32/uPlot.iife.min.js"));
  EXPECT_EQ(a.uplot_css,
            config::ReadFile(test::SourceDir() / "scenarios/vendor/uplot-1.6.32/uPlot.min.css"));
  EXPECT_GT(a.uplot_js.size(), 16000u);  // more than one chunk, joined
  EXPECT_NE(ReportHtml(report_, dir_.path()).find(a.uplot_js), std::string::npos);
}

TEST_F(ReportRun, TheCarsTrackStopLinesAndMarksAreWhereTheyHappened) {
  const json data = DataOf(ReportHtml(report_, dir_.path()));
  ASSERT_EQ(data["cars"].size(), 1u);
  const json& car = data["cars"][0];
  EXPECT_EQ(car["name"], "nigel_1");
  EXPECT_EQ(car["track"]["t"].size(), 1601u);  // below the thinning limit: every step
  EXPECT_DOUBLE_EQ(car["track"]["x"].back().get<double>(), 4.0);
  // Only the line facing its way (head 3), not the opposite one (head 4); its front (0.229 m
  // ahead of the rear axle) reaches x = 2 at (2 - 0.229) / 0.25 s.
  ASSERT_EQ(car["stop_lines"].size(), 1u);
  EXPECT_EQ(car["stop_lines"][0]["heads"], json::array({3}));
  const double front = RunWorld::Car{}.centre_ahead_m + RunWorld::Car{}.length_m / 2;
  EXPECT_NEAR(car["stop_lines"][0]["t_cross"].get<double>(), (2 - front) / 0.25, 0.011);
  ASSERT_EQ(car["marks"].size(), 1u);
  EXPECT_EQ(car["marks"][0]["kind"], "red_light");
  // Where its tail was (the red light's rule): 0.088 m behind the rear axle.
  const double tail = RunWorld::Car{}.centre_ahead_m - RunWorld::Car{}.length_m / 2;
  EXPECT_NEAR(car["marks"][0]["x"].get<double>(), 0.25 * 9.0 + tail, 0.0011);
  // Head 3: green, yellow, then red to the end; head 4 red throughout.
  EXPECT_EQ(data["heads"]["3"]["bands"], json::parse("[[0,5,3],[5,8,2],[8,16,1]]"));
  EXPECT_EQ(data["heads"]["4"]["bands"], json::parse("[[0,16,1]]"));
  // The map: the lanes, the obstacle, both stop lines; bounds around all of them (the lanes
  // with their width).
  EXPECT_EQ(data["world"]["lanes"].size(), 2u);
  EXPECT_EQ(data["world"]["statics"][0]["kind"], "obstacle");
  EXPECT_EQ(data["world"]["stop_lines"].size(), 2u);
  EXPECT_EQ(data["world"]["bounds"], json::parse("[-0.15,-0.15,4.15,0.55]"));
  EXPECT_TRUE(data["notes"].empty());
}

TEST_F(ReportRun, TheTimeLineHasEveryLogsEventsInRows) {
  const json data = DataOf(ReportHtml(report_, dir_.path()));
  const json& t = data["timeline"];
  EXPECT_EQ(t["rows"],
            json::parse(R"(["scenario","SPaT centre","SCM events","V2I nigel_1","nigel_1"])"));
  std::map<std::string, std::vector<std::string>> labels;
  for (const json& m : t["marks"]) {
    labels[t["rows"][m["row"].get<std::size_t>()].get<std::string>()].push_back(
        m["label"].get<std::string>());
  }
  EXPECT_EQ(labels["scenario"],
            (std::vector<std::string>{"mode centre → flash", "place obstacle box",
                                      "lamp red of head 2 burnt_out", "surge of 5 bus from a"}));
  // SPaT: the first message, then the change to failure flash (not the repeat).
  EXPECT_EQ(labels["SPaT centre"],
            (std::vector<std::string>{"plan day +fixed_time", "+failure_flash −fixed_time"}));
  EXPECT_EQ(labels["SCM events"], std::vector<std::string>{"</script><b>flash</b>"});
  EXPECT_EQ(labels["V2I nigel_1"], (std::vector<std::string>{"#1 preemption", "#1 rejected"}));
  EXPECT_EQ(labels["nigel_1"], (std::vector<std::string>{"red light", "stop line"}));
  EXPECT_EQ(data["intersections"]["7"], "centre");
}

TEST_F(ReportRun, ALongTrackIsThinnedAndKeepsItsLastSample) {
  std::string truth = "t_s,vehicle,x_m,y_m,yaw_rad,vx_mps,vy_mps,yaw_rate_radps\n";
  const int n = 10000;
  for (int i = 0; i < n; ++i) {
    truth += fmt::format("{:.6f},nigel_1,{:.6f},0,0,0.1,0,0\n", 0.01 * i, 0.001 * i);
  }
  Write("logs/ground_truth.csv", truth);
  const json data = DataOf(ReportHtml(report_, dir_.path()));
  const json& track = data["cars"][0]["track"];
  EXPECT_LE(track["t"].size(), internal::kMaxTrackSamples);
  EXPECT_GE(track["t"].size(), internal::kMaxTrackSamples / 2);
  EXPECT_DOUBLE_EQ(track["t"].back().get<double>(), 0.01 * (n - 1));
  EXPECT_DOUBLE_EQ(track["x"].back().get<double>(), 0.001 * (n - 1));
}

TEST_F(ReportRun, AMissingLogIsNamedOnThePageNotAnError) {
  fs::remove(dir_.path() / "logs/lamps.csv");
  fs::remove(dir_.path() / "logs/requests.jsonl");
  const json data = DataOf(ReportHtml(report_, dir_.path()));
  EXPECT_EQ(data["notes"], json::parse(R"(["lamps.csv: missing","requests.jsonl: missing"])"));
  EXPECT_TRUE(data["heads"].empty());
}

TEST_F(ReportRun, ABrokenLogIsRefusedNamingTheFileAndLine) {
  Write("logs/lamps.csv", "t_s,head,state\n0.0,3,3\n1.0,x,1\n");
  const std::string message = test::ErrorMessage([&] { (void)ReportHtml(report_, dir_.path()); });
  EXPECT_NE(message.find("lamps.csv:3: \"x\" is not a number"), std::string::npos) << message;
  Write("logs/lamps.csv", "t_s,head,state\n");
  Write("logs/events.jsonl", "{\"t_s\": 1}\nnot json\n");
  const std::string broken = test::ErrorMessage([&] { (void)ReportHtml(report_, dir_.path()); });
  EXPECT_NE(broken.find("events.jsonl:2:"), std::string::npos) << broken;
}

// ---- summary.html ----

json Summary() {
  return json::parse(R"({
    "sweep": {"name": "s", "file": "/path/sweep.yaml"}, "runs_total": 3, "runs_done": 3,
    "runs_failed": 1, "metrics": ["collisions", "time_to_goal_s"],
    "variants": [
      {"name": "driver", "parameters": {"agent": "driver"},
       "runs": [
         {"id": "driver_seed1", "seed": 1, "passed": true, "exit_code": 0,
          "report": "runs/driver_seed1/report.json",
          "metrics": {"collisions": 0, "time_to_goal_s": 37.5}},
         {"id": "driver_seed2", "seed": 2, "passed": false, "exit_code": 1,
          "report": "runs/driver seed#2/report.json",
          "metrics": {"collisions": 1, "time_to_goal_s": null}}],
       "stats": {"collisions": {"n": 2, "mean": 0.5, "std": 0.7, "min": 0, "max": 1, "worst": 1}}},
      {"name": "careful", "runs": [
         {"id": "careful_seed1", "seed": 1, "passed": true, "exit_code": 0,
          "report": "runs/careful_seed1/report.json",
          "metrics": {"collisions": 0, "time_to_goal_s": 40.5}}]}]})");
}

TEST(SummaryHtml, LinksEachRunsReportAndCompletesMissingStatistics) {
  const std::string page = SummaryHtml(Summary());
  const std::string open = "<script type=\"application/json\" id=\"page-data\">";
  const auto from = page.find(open) + open.size();
  const json data = json::parse(page.substr(from, page.find("</script>", from) - from));
  const json& driver = data["variants"][0];
  EXPECT_EQ(driver["runs"][0]["html"], "runs/driver_seed1/report.html");
  EXPECT_EQ(driver["runs"][1]["html"], "runs/driver seed#2/report.html");
  // Given statistics are kept; missing ones computed from the runs that measured the metric.
  EXPECT_EQ(driver["stats"]["collisions"]["worst"], 1);
  EXPECT_EQ(driver["stats"]["time_to_goal_s"]["n"], 1);
  EXPECT_DOUBLE_EQ(driver["stats"]["time_to_goal_s"]["mean"].get<double>(), 37.5);
  const json& careful = data["variants"][1]["stats"];
  EXPECT_EQ(careful["collisions"]["n"], 1);
  EXPECT_DOUBLE_EQ(careful["time_to_goal_s"]["max"].get<double>(), 40.5);
  EXPECT_EQ(Count(page, "</script>"), 4u);
  EXPECT_NE(page.find("<title>s — sweep summary</title>"), std::string::npos);
}

TEST(SummaryHtml, WithoutAListOfMetricsEveryMetricOfTheRunsIsShown) {
  json summary = Summary();
  summary.erase("metrics");
  const std::string page = SummaryHtml(summary);
  const std::string open = "<script type=\"application/json\" id=\"page-data\">";
  const auto from = page.find(open) + open.size();
  const json data = json::parse(page.substr(from, page.find("</script>", from) - from));
  EXPECT_EQ(data["metrics"], json::parse(R"(["collisions","time_to_goal_s"])"));
}

TEST(SummaryHtml, RefusesASummaryWithoutVariantsOrRuns) {
  EXPECT_EQ(test::ErrorMessage([] { (void)SummaryHtml(json::parse(R"({"sweep": {}})")); }),
            "summary: not an object with a list of variants");
  EXPECT_EQ(test::ErrorMessage(
                [] { (void)SummaryHtml(json::parse(R"({"variants": [{"name": "a"}]})")); }),
            "summary: variant a has no list of runs");
}

}  // namespace
}  // namespace autodrive::scenarios
