// The controller model's NTCIP names (docs/controller.md, "NTCIP 1202 names") against the public
// NTCIP 1202 MIB's objects as listed in ../shared/ntcip1202_asc_objects.csv (a compile of the
// 1202 ASC MIB nobody on the team wrote): every object the table names exists with the OID the
// table gives and the unit the MIB's DESCRIPTION text gives, and every NTCIP name the model's
// header uses and every timing key of the city file is in the table. No invented names.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "common/config.h"
#include "common/test_support.h"

namespace autodrive::scm {
namespace {

struct Row {
  std::string field, object, oid, unit, key;
};

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? "" : s.substr(b, e - b + 1);
}

std::string Unquote(std::string s) {
  s = Trim(s);
  if (s.size() >= 2 && s.front() == '`' && s.back() == '`') s = s.substr(1, s.size() - 2);
  return s;
}

/// The rows of the table under "## NTCIP 1202 names" of docs/controller.md.
std::vector<Row> DocTable() {
  const std::string text = config::ReadFile(test::SourceDir() / "docs" / "controller.md");
  const auto section = text.find("## NTCIP 1202 names");
  EXPECT_NE(section, std::string::npos);
  std::istringstream in(text.substr(section));
  std::vector<Row> rows;
  std::string line;
  bool header = false;
  while (std::getline(in, line)) {
    if (line.rfind("| model field", 0) == 0) {
      header = true;
      continue;
    }
    if (!header) continue;
    if (line.rfind("|", 0) != 0) {
      if (!rows.empty()) break;
      continue;
    }
    if (line.rfind("| ---", 0) == 0) continue;
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream cs(line.substr(1));
    while (std::getline(cs, cell, '|')) cells.push_back(Trim(cell));
    EXPECT_GE(cells.size(), 5u) << line;
    if (cells.size() < 5) continue;
    rows.push_back({cells[0], Unquote(cells[1]), cells[2], cells[3], cells[4]});
  }
  return rows;
}

/// name -> oid of the MIB's objects.
std::map<std::string, std::string> MibObjects() {
  const auto path = test::SourceDir() / ".." / "shared" / "ntcip1202_asc_objects.csv";
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  std::map<std::string, std::string> objects;
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "oid,name,group,conformance");
  while (std::getline(in, line)) {
    const auto comma = line.find(',');
    const auto comma2 = line.find(',', comma + 1);
    if (comma == std::string::npos || comma2 == std::string::npos) continue;
    objects[line.substr(comma + 1, comma2 - comma - 1)] = line.substr(0, comma);
  }
  EXPECT_GT(objects.size(), 150u);
  return objects;
}

// The units of the objects, from the MIB's DESCRIPTION text (quoted in the controller research,
// ../shared/research/controller.md §2.2, §2.5, §2.7): walk, ped clear, min green and the maxes
// in seconds; passage, yellow, red clear and red revert in tenths; cycle and offset in seconds.
const std::map<std::string, std::string> kMibUnits{
    {"phaseNumber", "number"},
    {"phaseWalk", "s"},
    {"phasePedestrianClear", "s"},
    {"phaseMinimumGreen", "s"},
    {"phasePassage", "0.1 s"},
    {"phaseMaximum1", "s"},
    {"phaseMaximum2", "s"},
    {"phaseYellowChange", "0.1 s"},
    {"phaseRedClear", "0.1 s"},
    {"phaseRedRevert", "0.1 s"},
    {"phaseOptions", "bits"},
    {"phaseRing", "number"},
    {"phaseConcurrency", "phase numbers"},
    {"sequenceRingNumber", "number"},
    {"sequenceData", "phase numbers"},
    {"channelControlSource", "phase number"},
    {"patternCycleTime", "s"},
    {"patternOffsetTime", "s"},
    // The preempt table (asc.6.2.1; research §2.6): delay, minimum duration, minimum green, track
    // green, dwell green and maximum presence in seconds; the phases as phase numbers.
    {"preemptDelay", "s"},
    {"preemptMinimumDuration", "s"},
    {"preemptMinimumGreen", "s"},
    {"preemptTrackGreen", "s"},
    {"preemptDwellGreen", "s"},
    {"preemptMaximumPresence", "s"},
    {"preemptTrackPhase", "phase numbers"},
    {"preemptDwellPhase", "phase numbers"},
    {"preemptExitPhase", "phase numbers"},
    {"preemptState", "enumeration"},
};

TEST(NtcipNames, EveryObjectOfTheTableIsInTheMibWithItsOidAndUnit) {
  const auto mib = MibObjects();
  const auto rows = DocTable();
  ASSERT_GE(rows.size(), 15u);
  for (const Row& r : rows) {
    SCOPED_TRACE(r.object);
    const auto it = mib.find(r.object);
    ASSERT_NE(it, mib.end()) << r.object << " is no object of the NTCIP 1202 asc MIB";
    EXPECT_EQ(r.oid, it->second);
    const auto unit = kMibUnits.find(r.object);
    ASSERT_NE(unit, kMibUnits.end()) << "no MIB unit known for " << r.object;
    EXPECT_EQ(r.unit, unit->second);
  }
}

TEST(NtcipNames, EveryNtcipNameOfTheModelIsInTheTable) {
  std::set<std::string> documented;
  for (const Row& r : DocTable()) documented.insert(r.object);
  const std::string header = config::ReadFile(test::SourceDir() / "scm" / "core" / "ring_plan.h");
  // The NTCIP names in the header's comments: camelCase words of the MIB's tables.
  const std::regex name(
      R"(\b((?:phase|sequence|pattern|channel|split|coord|preempt|unit|ring)[A-Z][A-Za-z0-9]*)\b)");
  const auto mib = MibObjects();
  int found = 0;
  for (auto it = std::sregex_iterator(header.begin(), header.end(), name);
       it != std::sregex_iterator(); ++it) {
    const std::string n = (*it)[1];
    if (n == "phaseTable") continue;  // the table, not an object
    ++found;
    EXPECT_TRUE(mib.contains(n)) << n << " in ring_plan.h is no object of the MIB";
    EXPECT_TRUE(documented.contains(n)) << n << " in ring_plan.h is not in docs/controller.md";
  }
  EXPECT_GE(found, 15);
}

TEST(NtcipNames, EveryTimingKeyOfTheCityFileIsInTheTable) {
  std::string keys_column;
  for (const Row& r : DocTable()) keys_column += r.key + " ";
  const std::string config = config::ReadFile(test::SourceDir() / "scm" / "core" / "city_config.h");
  // The structs whose keys time or sequence a plan, or a pre-emption.
  for (const std::string s : {"TimingConfig", "PhaseConfig", "PlanConfig", "PriorityConfig"}) {
    const auto begin = config.find("struct " + s + " {");
    ASSERT_NE(begin, std::string::npos) << s;
    const auto end = config.find("\n};", begin);
    const std::string body = config.substr(begin, end - begin);
    const std::regex key(R"re(a\.(?:Optional|Required)\("([a-z_]+)")re");
    for (auto it = std::sregex_iterator(body.begin(), body.end(), key);
         it != std::sregex_iterator(); ++it) {
      const std::string k = (*it)[1];
      if (k == "name" || k == "type" || k == "phases" || k == "detectors") continue;
      // V2I priority's switch and its bus (TSP) limit: no preempt object (NTCIP 1211's).
      if (k == "enabled" || k == "max_extension_s") continue;
      EXPECT_NE(keys_column.find(k), std::string::npos)
          << s << "'s key " << k << " is not in docs/controller.md's NTCIP table";
    }
  }
}

}  // namespace
}  // namespace autodrive::scm
