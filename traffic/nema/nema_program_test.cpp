// The NEMA export of the city's plans (no SUMO run) and the call script.
#include "traffic/nema/nema_program.h"

#include <gtest/gtest.h>

#include <map>
#include <string>

#include <pugixml.hpp>

#include "traffic/nema/call_script.h"

#include "common/test_support.h"
#include "scm/core/city.h"
#include "scm/core/ring_plan.h"

namespace autodrive::traffic::nema {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;

const scm::City& DrivingSchool() {
  static const scm::City city =
      scm::LoadCity(test::SourceDir() / "config/cities/driving_school.yaml");
  return city;
}

// The tlLogic of an exported file, its params by key and its phases by name.
struct Parsed {
  pugi::xml_document doc;
  pugi::xml_node tl;
  std::map<std::string, std::string> params;
  std::map<std::string, pugi::xml_node> phases;
};

void Parse(const std::string& xml, Parsed& out) {
  ASSERT_TRUE(out.doc.load_string(xml.c_str())) << xml;
  out.tl = out.doc.child("additional").child("tlLogic");
  ASSERT_TRUE(out.tl) << xml;
  for (pugi::xml_node p : out.tl.children("param")) {
    out.params[p.attribute("key").as_string()] = p.attribute("value").as_string();
  }
  for (pugi::xml_node p : out.tl.children("phase")) out.phases[p.attribute("name").as_string()] = p;
}

TEST(NemaExport, DrivingSchoolDayPlanIsOneRingRepeatedWithMaxRecallAndOneApproachAPhase) {
  const scm::City& city = DrivingSchool();
  const NemaProgram p = NemaProgramOf(city, FindPlan(city, "driving_school_crossing", "day"));
  EXPECT_EQ(p.tls, "driving_school_crossing");
  EXPECT_EQ(p.links, 12u);
  EXPECT_EQ(p.cycle, seconds(72));  // 4 x (8 + 3 + 7)
  EXPECT_EQ(p.plan_offset, seconds(0));
  EXPECT_EQ(p.offset, seconds(18));  // the coordinated phase 2's green: after phase 1's 18 s

  Parsed x;
  Parse(NemaAdditionalXml(p), x);
  EXPECT_STREQ(x.tl.attribute("id").as_string(), "driving_school_crossing");
  EXPECT_STREQ(x.tl.attribute("programID").as_string(), "NEMA");
  EXPECT_STREQ(x.tl.attribute("type").as_string(), "NEMA");
  EXPECT_STREQ(x.tl.attribute("offset").as_string(), "18");
  const std::map<std::string, std::string> params = {
      {"ring1", "1,2,3,4"},
      {"ring2", "1,2,3,4"},
      {"barrierPhases", "4,4"},
      {"coordinatePhases", "2,2"},
      {"minRecall", ""},
      {"maxRecall", "1,2,3,4"},
      {"latchingDetectors", ""},
      {"fixForceOff", "true"},
      {"coordinate-mode", "true"},
      {"controllerType", "TS2"},
      {"total-cycle-length", "72"},
  };
  EXPECT_EQ(x.params, params);
  // Link i is movement i of the intersection; each group is one approach's three movements, in
  // the map's order: east (0-2), north (3-5), west (6-8), south (9-11).
  const std::map<std::string, std::string> states = {
      {"1", "GGGrrrrrrrrr"}, {"2", "rrrGGGrrrrrr"}, {"3", "rrrrrrGGGrrr"}, {"4", "rrrrrrrrrGGG"}};
  ASSERT_EQ(x.phases.size(), 4u);
  for (const auto& [name, state] : states) {
    SCOPED_TRACE("phase " + name);
    const pugi::xml_node ph = x.phases.at(name);
    EXPECT_STREQ(ph.attribute("state").as_string(), state.c_str());
    EXPECT_STREQ(ph.attribute("duration").as_string(), "99");
    EXPECT_STREQ(ph.attribute("minDur").as_string(), "5");
    EXPECT_STREQ(ph.attribute("maxDur").as_string(), "8");
    EXPECT_STREQ(ph.attribute("vehext").as_string(), "0");
    EXPECT_STREQ(ph.attribute("yellow").as_string(), "3");
    EXPECT_STREQ(ph.attribute("red").as_string(), "7");
  }
  // The same, from the model: the 'G's of phase k are the movements of its group.
  const scm::IntersectionModel& model = *city.Find("driving_school_crossing");
  const maps::Intersection& map_x = city.map.intersection(model.id);
  for (const NemaPhase& phase : p.phases) {
    ASSERT_EQ(phase.groups.size(), 1u);
    for (std::size_t i = 0; i < map_x.movements.size(); ++i) {
      const bool in_group =
          std::ranges::find(model.groups[phase.groups[0]].movements, map_x.movements[i]) !=
          model.groups[phase.groups[0]].movements.end();
      EXPECT_EQ(phase.state[i] == 'G', in_group) << "phase " << phase.number << " link " << i;
    }
  }
}

TEST(NemaExport, ActuatedPlanHasItsPassageAndNoRecallAndIsNotCoordinated) {
  const scm::City& city = DrivingSchool();
  const NemaProgram p = NemaProgramOf(city, FindPlan(city, "driving_school_crossing", "evening"));
  Parsed x;
  Parse(NemaAdditionalXml(p, {"/tmp/switches.xml", "/tmp/states.xml"}), x);
  EXPECT_STREQ(x.tl.attribute("offset").as_string(), "0");
  EXPECT_EQ(x.params.at("minRecall"), "");  // every group has a detector: no recall
  EXPECT_EQ(x.params.at("maxRecall"), "");
  EXPECT_EQ(x.params.at("coordinate-mode"), "false");
  EXPECT_EQ(x.params.at("fixForceOff"), "false");
  EXPECT_EQ(x.params.at("total-cycle-length"), "100");  // 4 x (15 + 3 + 7)
  EXPECT_STREQ(x.phases.at("3").attribute("vehext").as_string(), "2");
  EXPECT_STREQ(x.phases.at("3").attribute("maxDur").as_string(), "15");
  int events = 0;
  for (pugi::xml_node e : x.doc.child("additional").children("timedEvent")) {
    ++events;
    EXPECT_STREQ(e.attribute("source").as_string(), "driving_school_crossing");
  }
  EXPECT_EQ(events, 2);
}

// A ring plan of the Driving School's day plan to spoil.
scm::RingPlan DayRing() {
  const scm::City& city = DrivingSchool();
  const scm::IntersectionModel& x = *city.Find("driving_school_crossing");
  return scm::RingPlanOf(x, x.plans[*x.PlanIndex("day")]);
}

std::string Refusal(const scm::RingPlan& plan) {
  const scm::City& city = DrivingSchool();
  const scm::IntersectionModel& x = *city.Find("driving_school_crossing");
  return test::ErrorMessage([&] { (void)NemaProgramOf(city.map.intersection(x.id), x, plan); });
}

TEST(NemaExport, RefusesWhatSumosNemaControllerCannotRunNamingIt) {
  {
    scm::RingPlan plan = DayRing();
    plan.phases[1].groups.push_back(0);  // east in phases 1 and 2
    EXPECT_NE(Refusal(plan).find("group 1 (east) is driven by phases 1 and 2"), std::string::npos)
        << Refusal(plan);
  }
  {
    scm::RingPlan plan = DayRing();
    plan.phases.push_back(plan.phases[0]);
    plan.phases.back().number = 5;
    plan.phases.back().groups = {};
    plan.rings[0].push_back(5);
    EXPECT_NE(Refusal(plan).find("ring 1 has 5 phases"), std::string::npos) << Refusal(plan);
  }
  {
    scm::RingPlan plan = DayRing();
    plan.phases[2].recall = scm::Recall::kPed;
    EXPECT_NE(Refusal(plan).find("phase 3 has ped recall"), std::string::npos) << Refusal(plan);
  }
  {
    scm::RingPlan plan = DayRing();
    plan.phases[0].walk = seconds(7);
    EXPECT_NE(Refusal(plan).find("phase 1 has a walk"), std::string::npos) << Refusal(plan);
  }
  {
    scm::RingPlan plan = DayRing();
    plan.rings.push_back({});
    EXPECT_NE(Refusal(plan).find("2 rings"), std::string::npos) << Refusal(plan);
  }
  const scm::City& city = DrivingSchool();
  const std::string flash = test::ErrorMessage(
      [&] { (void)NemaProgramOf(city, FindPlan(city, "driving_school_crossing", "night")); });
  EXPECT_NE(flash.find("plan night (flash)"), std::string::npos) << flash;
  EXPECT_NE(flash.find("no phases"), std::string::npos) << flash;
  const std::string plan =
      test::ErrorMessage([&] { (void)FindPlan(city, "driving_school_crossing", "noon"); });
  EXPECT_NE(plan.find("no plan \"noon\" (it has: day, evening, night, off)"), std::string::npos)
      << plan;
  const std::string where = test::ErrorMessage([&] { (void)FindPlan(city, "nowhere", "day"); });
  EXPECT_NE(where.find("(it has: driving_school_crossing)"), std::string::npos) << where;
}

TEST(NemaExport, TwoAndThreePhaseRingsFillSumosFourPlacesAroundTheMiddleBarrier) {
  scm::RingPlan three = DayRing();
  three.phases.pop_back();
  three.rings[0].pop_back();
  three.cycle = seconds(54);
  const scm::City& city = DrivingSchool();
  const scm::IntersectionModel& x = *city.Find("driving_school_crossing");
  const NemaProgram p3 = NemaProgramOf(city.map.intersection(x.id), x, three);
  EXPECT_EQ(p3.rings[0], (std::vector<std::uint32_t>{1, 2, 3, 0}));
  EXPECT_EQ(p3.barrier_phases[0], 3u);
  EXPECT_EQ(p3.coordinate_phases[0], 2u);
  scm::RingPlan two = three;
  two.phases.pop_back();
  two.rings[0].pop_back();
  two.cycle = seconds(36);
  two.offset = seconds(5);
  const NemaProgram p2 = NemaProgramOf(city.map.intersection(x.id), x, two);
  EXPECT_EQ(p2.rings[0], (std::vector<std::uint32_t>{1, 0, 2, 0}));
  EXPECT_EQ(p2.barrier_phases[0], 2u);
  EXPECT_EQ(p2.coordinate_phases[0], 1u);
  EXPECT_EQ(p2.offset, seconds(5));  // the coordinated phase is phase 1
}

TEST(NemaExport, SumoSecondsHaveNoTrailingZeros) {
  EXPECT_EQ(SumoSeconds(seconds(8)), "8");
  EXPECT_EQ(SumoSeconds(milliseconds(2500)), "2.5");
  EXPECT_EQ(SumoSeconds(milliseconds(125)), "0.125");
  EXPECT_EQ(SumoSeconds(seconds(0)), "0");
}

TEST(CallScript, ParsesPhasesAndTimesAndSaysWhichLineIsWrong) {
  const CallScript s = ParseCallScript("# phase on off\n2 50 120\n\n4 10.5  # to the end\n", "x");
  ASSERT_EQ(s.calls.size(), 2u);
  EXPECT_EQ(s.calls[0], (PhaseCall{2, seconds(50), seconds(120)}));
  EXPECT_EQ(s.calls[1], (PhaseCall{4, milliseconds(10500), std::nullopt}));
  EXPECT_TRUE(s.Called(2, seconds(50)));
  EXPECT_FALSE(s.Called(2, seconds(120)));
  EXPECT_TRUE(s.Called(4, seconds(9999)));
  EXPECT_FALSE(s.Called(1, seconds(60)));

  EXPECT_EQ(test::ErrorMessage([] { (void)ParseCallScript("2 5\n9 1 2\n", "calls.txt"); }),
            "calls.txt:2: the phase must be a NEMA phase number 1..8, got 9");
  EXPECT_EQ(test::ErrorMessage([] { (void)ParseCallScript("2 5 4\n", "c"); }),
            "c:1: off_s must be after on_s (5), got 4");
  EXPECT_EQ(test::ErrorMessage([] { (void)ParseCallScript("2 soon\n", "c"); }),
            "c:1: on_s must be a number, got \"soon\"");
  EXPECT_EQ(test::ErrorMessage([] { (void)ParseCallScript("2\n", "c"); }),
            "c:1: expected \"phase on_s [off_s]\", got \"2\"");
}

}  // namespace
}  // namespace autodrive::traffic::nema
