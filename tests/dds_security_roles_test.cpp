// The DDS Security grants, checked against Cyclone DDS itself. The table "Who may publish and
// subscribe each topic" of docs/security.md is read from the file; a keystore made by
// scripts/autodrive-keystore (from config/security/roles.conf) in the test's own temporary
// folder gives each shipped role an identity; for each role, tests/dds_security_probe.c (plain
// C, Cyclone's API only) holds that identity and tries a writer and a reader on every topic of
// the table, and on topics the table does not list. The answers must be the table's, so the doc
// and what is enforced cannot drift apart.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/dds/topics.h"
#include "common/process.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr int kNotAllowedBySecurity = -13;  // DDS_RETCODE_NOT_ALLOWED_BY_SECURITY
constexpr char kTableHeading[] = "### Who may publish and subscribe each topic";

// Every shipped role and the enclave that holds it here. The vehicle and the operator are the
// "own" instances of the table's rows (nigel_1, alice); nigel_2 and bob are the others.
const std::vector<std::pair<std::string, std::string>>& Roles() {
  static const std::vector<std::pair<std::string, std::string>> roles = {
      {"scm", "/autodrive/scm"},
      {"infra", "/autodrive/infra/lights1"},
      {"operator", "/autodrive/operator/alice"},
      {"viewer", "/autodrive/viewer/carol"},
      {"vehicle", "/autodrive/vehicle/nigel_1"},
      {"sim", "/autodrive/sim"},
      {"eye", "/autodrive/eye"},
      {"traffic", "/autodrive/traffic"},
      {"launcher", "/autodrive/launcher"},
  };
  return roles;
}

// Placeholders of the table's topic names and what each stands for in the own instance and in
// the other one (another car, another operator).
struct Placeholder {
  std::string name, own, other, pattern;
};
const std::vector<Placeholder>& Placeholders() {
  static const std::vector<Placeholder> placeholders = {
      {"<i>", "1", "1", "[0-9]+"},
      {"<n>", "1", "2", "[0-9]+"},
      {"<name>", "alice", "bob", "[A-Za-z_][A-Za-z0-9_]*"},
      {"<camera>", "top", "top", "[A-Za-z_][A-Za-z0-9_]*"},
      {"<leaf>", "stack_topic", "stack_topic", "[A-Za-z_][A-Za-z0-9_]*"},
  };
  return placeholders;
}

// One cell of roles: the roles it lists, those of them marked "(own)", or every role ("all").
struct Grant {
  std::set<std::string> roles;
  std::set<std::string> own;
};

// One row of the table.
struct Row {
  int line = 0;  // in docs/security.md
  std::string topic;
  Grant publish, subscribe;
};

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

std::vector<std::string> SplitCells(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream in(line.substr(1));  // after the leading '|'
  std::string cell;
  while (std::getline(in, cell, '|')) cells.push_back(Trim(cell));
  return cells;
}

Grant ParseGrant(const std::string& cell, int line) {
  Grant grant;
  if (cell.empty() || cell == "-" || cell == "—") return grant;
  std::stringstream in(cell);
  std::string item;
  while (std::getline(in, item, ',')) {
    item = Trim(item);
    bool own = false;
    if (item.ends_with("(own)")) {
      own = true;
      item = Trim(item.substr(0, item.size() - 5));
    }
    if (item == "all") {
      for (const auto& [role, enclave] : Roles()) grant.roles.insert(role);
      continue;
    }
    const bool known =
        std::any_of(Roles().begin(), Roles().end(), [&](const auto& r) { return r.first == item; });
    EXPECT_TRUE(known) << "docs/security.md:" << line << ": unknown role '" << item << "'";
    grant.roles.insert(item);
    if (own) grant.own.insert(item);
  }
  return grant;
}

// The rows of the table after kTableHeading in docs/security.md.
std::vector<Row> ReadTable() {
  const fs::path doc = test::SourceDir() / "docs/security.md";
  std::ifstream in(doc);
  EXPECT_TRUE(in) << "cannot read " << doc;
  std::vector<Row> rows;
  std::string line;
  int number = 0;
  bool in_section = false, in_table = false;
  while (std::getline(in, line)) {
    ++number;
    if (!in_section) {
      in_section = line == kTableHeading;
      continue;
    }
    if (!line.starts_with("|")) {
      if (in_table) break;  // the table ended
      continue;
    }
    in_table = true;
    const std::vector<std::string> cells = SplitCells(line);
    if (cells.size() < 4 || cells[0] == "topic" || cells[0].starts_with("---")) continue;
    EXPECT_TRUE(cells[0].size() > 2 && cells[0].front() == '`' && cells[0].back() == '`')
        << "docs/security.md:" << number << ": the topic in backticks, got " << cells[0];
    rows.push_back(Row{number, cells[0].substr(1, cells[0].size() - 2),
                       ParseGrant(cells[1], number), ParseGrant(cells[2], number)});
  }
  EXPECT_TRUE(in_section) << "no '" << kTableHeading << "' in " << doc;
  return rows;
}

std::string Instance(std::string topic, bool own) {
  for (const Placeholder& p : Placeholders()) {
    for (auto at = topic.find(p.name); at != std::string::npos; at = topic.find(p.name)) {
      topic.replace(at, p.name.size(), own ? p.own : p.other);
    }
  }
  return topic;
}

// The row's topic as a regular expression over concrete topic names.
std::regex RowPattern(const std::string& topic) {
  std::string re;
  for (std::size_t i = 0; i < topic.size();) {
    bool placeholder = false;
    for (const Placeholder& p : Placeholders()) {
      if (topic.compare(i, p.name.size(), p.name) == 0) {
        re += p.pattern;
        i += p.name.size();
        placeholder = true;
        break;
      }
    }
    if (placeholder) continue;
    if (std::string_view("\\^$.|?*+()[]{}").find(topic[i]) != std::string_view::npos) re += '\\';
    re += topic[i++];
  }
  return std::regex(re);
}

// A concrete topic to probe and the roles that must be allowed to write and to read it.
struct Probe {
  std::string topic;
  std::set<std::string> writers, readers;
  std::string source;  // where the expectation comes from
};

std::set<std::string> Allowed(const Grant& grant, bool own_instance) {
  std::set<std::string> roles;
  for (const std::string& role : grant.roles) {
    if (own_instance || !grant.own.contains(role)) roles.insert(role);
  }
  return roles;
}

// Topics under the lab's prefixes that no row lists: nobody may use them (a broad pattern such
// as rt/autodrive/scm/* in roles.conf would be caught here).
const std::vector<std::string>& UnlistedTopics() {
  static const std::vector<std::string> topics = {
      "rt/unlisted",
      "rt/autodrive/unlisted",
      "rt/autodrive/scm/unlisted",
      "rt/autodrive/scm/operator/unlisted",
      "rt/autodrive/scm/operator/alice/unlisted",
      "rt/autodrive/signal_1/unlisted",
      "rt/autodrive/infra/unlisted",
      "rt/autodrive/sim/unlisted",
      "rt/autodrive/eye/unlisted",
      "rt/autodrive/eye/top/unlisted",
      "rt/autodrive/cameras/top/unlisted",
      "rt/autodrive/cameras/unlisted",
  };
  return topics;
}

// What the probe said about one topic: the return codes, writer and reader unset when the
// topic itself was refused.
struct Answer {
  int topic = 1;
  std::optional<int> writer, reader;
};

struct ToolResult {
  int exit_code = -1;
  std::vector<std::string> lines;  // stdout and stderr
};

ToolResult RunTool(const std::vector<std::string>& args) {
  std::vector<std::string> argv{"/bin/sh", "-c", "exec \"$0\" \"$@\" 2>&1"};
  argv.insert(argv.end(), args.begin(), args.end());
  ChildProcess child(argv);
  ToolResult result;
  while (auto line = child.ReadLine(120s)) result.lines.push_back(*line);
  result.exit_code = child.Wait(120s).value_or(-1);
  return result;
}

std::string Transcript(const ToolResult& r) {
  std::string text;
  for (const auto& l : r.lines) text += "  | " + l + "\n";
  return text;
}

class DdsSecurityRoles : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string pattern =
        (fs::temp_directory_path() / "autodrive_dds_security_roles_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    keystore_ = dir_ / "keystore";
    const ToolResult made = RunTool(
        {ExecutableDir() + "/autodrive-keystore", "city", keystore_.string(), "--operators",
         "alice,bob", "--viewers", "carol", "--infra", "lights1", "--vehicles", "nigel_1,nigel_2"});
    ASSERT_EQ(made.exit_code, 0) << Transcript(made);
    ready_ = true;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void SetUp() override { ASSERT_TRUE(ready_) << "the keystore could not be made"; }

  // Runs the probe as `enclave` on `topics`; its answers by topic.
  static std::map<std::string, Answer> ProbeAs(const std::string& enclave,
                                               const std::vector<std::string>& topics) {
    std::vector<std::string> argv{ExecutableDir() + "/dds_security_probe",
                                  "--keystore",
                                  keystore_.string(),
                                  "--enclave",
                                  enclave,
                                  "--partition",
                                  "security_roles_" + std::to_string(::getpid())};
    argv.insert(argv.end(), topics.begin(), topics.end());
    const ToolResult r = RunTool(argv);
    EXPECT_EQ(r.exit_code, 0) << enclave << "\n" << Transcript(r);
    std::map<std::string, Answer> answers;
    const std::regex line_re(
        R"(^probe (\S+) topic=(-?[0-9]+) writer=(-?[0-9]+|-) reader=(-?[0-9]+|-)$)");
    bool joined = false;
    for (const std::string& line : r.lines) {
      joined = joined || line == "joined " + enclave;
      std::smatch m;
      if (!std::regex_match(line, m, line_re)) continue;
      Answer a;
      a.topic = std::stoi(m[2]);
      if (m[3] != "-") a.writer = std::stoi(m[3]);
      if (m[4] != "-") a.reader = std::stoi(m[4]);
      answers[m[1]] = a;
    }
    EXPECT_TRUE(joined) << enclave << "\n" << Transcript(r);
    EXPECT_EQ(answers.size(), topics.size()) << enclave << "\n" << Transcript(r);
    return answers;
  }

  static inline fs::path dir_;
  static inline fs::path keystore_;
  static inline bool ready_ = false;
};

// The acceptance point of the forged-heartbeat defect, on its own: a light host's identity may
// read the SCM's heartbeat and its heads' commands but Security refuses it a writer on either
// (-13, Cyclone's own answer to a plain C client); the SCM's identity may write both.
TEST_F(DdsSecurityRoles, ALightHostCannotWriteTheScmsHeartbeatNorALightCommand) {
  const std::vector<std::string> topics = {"rt/autodrive/scm/heartbeat",
                                           "rt/autodrive/signal_1/command"};
  const auto infra = ProbeAs("/autodrive/infra/lights1", topics);
  const auto scm = ProbeAs("/autodrive/scm", topics);
  for (const std::string& topic : topics) {
    SCOPED_TRACE(topic);
    ASSERT_TRUE(infra.contains(topic));
    EXPECT_EQ(infra.at(topic).topic, 0) << "it reads the topic, so it may create it";
    EXPECT_EQ(infra.at(topic).writer, kNotAllowedBySecurity);
    EXPECT_EQ(infra.at(topic).reader, 0);
    ASSERT_TRUE(scm.contains(topic));
    EXPECT_EQ(scm.at(topic).topic, 0);
    EXPECT_EQ(scm.at(topic).writer, 0) << "the SCM writes it";
  }
}

// Every role against every row of the table (and the topics no row lists): each writer and
// reader is made exactly when the table lists the role, and each refusal is Security's.
TEST_F(DdsSecurityRoles, EveryRoleMayUseExactlyTheTopicsTheTableGivesIt) {
  const std::vector<Row> rows = ReadTable();
  ASSERT_GE(rows.size(), 30u) << "docs/security.md's table was not read";
  std::vector<Probe> probes;
  std::set<std::string> seen;
  for (const Row& row : rows) {
    const bool has_own = !row.publish.own.empty() || !row.subscribe.own.empty();
    for (const bool own : {true, false}) {
      if (!own && !has_own) continue;
      Probe p{Instance(row.topic, own), Allowed(row.publish, own), Allowed(row.subscribe, own),
              "docs/security.md:" + std::to_string(row.line) + (own ? "" : " (another's)")};
      EXPECT_TRUE(seen.insert(p.topic).second) << p.source << ": " << p.topic << " twice";
      probes.push_back(std::move(p));
    }
  }
  for (const std::string& topic : UnlistedTopics()) {
    for (const Row& row : rows) {
      EXPECT_FALSE(std::regex_match(topic, RowPattern(row.topic)))
          << topic << " is listed at docs/security.md:" << row.line;
    }
    probes.push_back(Probe{topic, {}, {}, "not in the table"});
  }
  std::vector<std::string> topics;
  for (const Probe& p : probes) topics.push_back(p.topic);

  for (const auto& [role, enclave] : Roles()) {
    SCOPED_TRACE(role + " (" + enclave + ")");
    const auto answers = ProbeAs(enclave, topics);
    for (const Probe& p : probes) {
      const auto found = answers.find(p.topic);
      if (found == answers.end()) {
        ADD_FAILURE() << "no answer for " << p.topic;
        continue;
      }
      const Answer& a = found->second;
      const bool may_write = p.writers.contains(role);
      const bool may_read = p.readers.contains(role);
      // A topic may be created when the permissions name it at all.
      EXPECT_EQ(a.topic == 0, may_write || may_read)
          << p.source << ": " << role << " dds_create_topic(" << p.topic << ") = " << a.topic;
      EXPECT_TRUE(a.topic == 0 || a.topic == kNotAllowedBySecurity)
          << p.topic << ": " << a.topic << " is not Security's refusal";
      if (a.topic != 0) continue;
      ASSERT_TRUE(a.writer.has_value() && a.reader.has_value()) << p.topic;
      EXPECT_EQ(*a.writer == 0, may_write)
          << p.source << ": " << role << (may_write ? " refused" : " allowed") << " a writer on "
          << p.topic << " (" << *a.writer << ")";
      EXPECT_EQ(*a.reader == 0, may_read)
          << p.source << ": " << role << (may_read ? " refused" : " allowed") << " a reader on "
          << p.topic << " (" << *a.reader << ")";
      EXPECT_TRUE(*a.writer == 0 || *a.writer == kNotAllowedBySecurity) << p.topic;
      EXPECT_TRUE(*a.reader == 0 || *a.reader == kNotAllowedBySecurity) << p.topic;
    }
  }
}

// The table covers the catalogue: every topic common/dds/topics.h names is one of its rows.
TEST_F(DdsSecurityRoles, EveryTopicOfTheCatalogueIsInTheTable) {
  namespace t = dds::topics;
  const std::vector<Row> rows = ReadTable();
  const VehicleId v(3);
  const SignalHeadId s(12);
  const std::vector<std::string> catalogue = {t::Throttle(v).name,
                                              t::Steering(v).name,
                                              t::LeftEncoder(v).name,
                                              t::RightEncoder(v).name,
                                              t::Ips(v).name,
                                              t::Imu(v).name,
                                              t::Lidar(v).name,
                                              t::FrontCamera(v).name,
                                              t::RearCamera(v).name,
                                              t::ThrottleCommand(v).name,
                                              t::SteeringCommand(v).name,
                                              t::HeadlightsCommand(v).name,
                                              t::IndicatorsCommand(v).name,
                                              t::GroundTruth(v).name,
                                              t::SignalCommand(s).name,
                                              t::SignalState(s).name,
                                              t::Spat().name,
                                              t::Map().name,
                                              t::Signs().name,
                                              t::Fleet().name,
                                              t::Traffic().name,
                                              t::Events().name,
                                              t::Devices().name,
                                              t::DeviceTable().name,
                                              t::Processes().name,
                                              t::Heartbeat().name,
                                              t::InfraHeartbeat().name,
                                              t::SignalRequests().name,
                                              t::SignalRequestStatus().name,
                                              t::OperatorRequests().name,
                                              t::OperatorRequests("carol").name,
                                              t::OperatorReplies().name,
                                              t::DeviceCommands().name,
                                              t::OverheadCamera("overhead").name,
                                              t::EyeFleet().name,
                                              t::EyeEvents().name,
                                              t::EyeDebugImage("overhead").name,
                                              t::Clock().name,
                                              t::SimStep().name,
                                              t::SimStepDone().name};
  for (const std::string& topic : catalogue) {
    // A car's namespace row (<leaf>) covers its every topic; each must also have its own row.
    const bool listed = std::any_of(rows.begin(), rows.end(), [&](const Row& row) {
      return row.topic.find("<leaf>") == std::string::npos &&
             std::regex_match(topic, RowPattern(row.topic));
    });
    EXPECT_TRUE(listed) << topic << " has no row in docs/security.md";
  }
}

// The test knows every role roles.conf ships (and roles.conf no role the test does not try).
TEST_F(DdsSecurityRoles, TheTestTriesEveryShippedRole) {
  const ToolResult roles = RunTool({ExecutableDir() + "/autodrive-keystore", "roles"});
  ASSERT_EQ(roles.exit_code, 0) << Transcript(roles);
  std::set<std::string> shipped;
  for (const std::string& line : roles.lines) {
    std::stringstream in(line);
    std::string role;
    if (in >> role && role != "all") shipped.insert(role);
  }
  std::set<std::string> tried;
  for (const auto& [role, enclave] : Roles()) tried.insert(role);
  EXPECT_EQ(shipped, tried);
}

}  // namespace
}  // namespace autodrive
