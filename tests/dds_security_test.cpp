// DDS Security with real processes. A keystore made by scripts/autodrive-keystore (copied into
// bin/) in the test's own temporary folder gives the lab's roles their identities; this test and
// dds_test_peer processes join with them and show that lights obey only the SCM, that operators
// and viewers can send only what their role allows, and that an unauthenticated participant
// sees and sends nothing. Each process holds one identity (the test process one per test).
#include <dds/dds.h>
#include <gtest/gtest.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/config.h"
#include "common/dds/conversions.h"
#include "common/dds/messages.h"
#include "common/dds/reader.h"
#include "common/dds/security.h"
#include "common/dds/topics.h"
#include "common/dds/writer.h"
#include "common/error.h"
#include "common/process.h"
#include "common/test_support.h"

namespace autodrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr char kLightCommand[] = "rt/autodrive/signal_1/command";
constexpr char kLight2Command[] = "rt/autodrive/signal_2/command";
constexpr char kLightState[] = "rt/autodrive/signal_1/state";
constexpr char kSharedRequest[] = "rt/autodrive/scm/operator/request";
constexpr char kAliceRequest[] = "rt/autodrive/scm/operator/alice/request";
constexpr char kBobRequest[] = "rt/autodrive/scm/operator/bob/request";
constexpr char kScmHeartbeat[] = "rt/autodrive/scm/heartbeat";
constexpr char kInfraHeartbeat[] = "rt/autodrive/infra/heartbeat";

constexpr char kScm[] = "/autodrive/scm";
constexpr char kLights[] = "/autodrive/infra/lights1";
constexpr char kAlice[] = "/autodrive/operator/alice";
constexpr char kCarol[] = "/autodrive/viewer/carol";
constexpr char kLauncher[] = "/autodrive/launcher";

struct ToolResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

// Runs bin/autodrive-keystore with `args`, its stderr merged into its stdout.
ToolResult RunKeystoreTool(const std::vector<std::string>& args) {
  std::vector<std::string> argv{"/bin/sh", "-c", "exec \"$0\" \"$@\" 2>&1",
                                ExecutableDir() + "/autodrive-keystore"};
  argv.insert(argv.end(), args.begin(), args.end());
  ChildProcess tool(argv);
  ToolResult result;
  while (auto line = tool.ReadLine(120s)) {
    result.output += *line + "\n";
  }
  result.exit_code = tool.Wait(120s).value_or(-1);
  return result;
}

std::string ReadFile(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A dds_test_peer process and everything it printed so far.
struct Peer {
  ChildProcess process;
  std::vector<std::string> lines;

  // Reads lines until one starts with `prefix` (returned) or `timeout` passes (nullopt).
  std::optional<std::string> Await(const std::string& prefix,
                                   std::chrono::milliseconds timeout = 30s) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      auto line = process.ReadLine(left);
      if (!line) return std::nullopt;
      lines.push_back(*line);
      if (line->starts_with(prefix)) return line;
    }
  }
  // Closes its stdin (it finishes) and collects the rest of its output and its exit code.
  int Finish() {
    process.CloseStdin();
    while (auto line = process.ReadLine(30s)) lines.push_back(*line);
    return process.Wait(30s).value_or(-1);
  }
  [[nodiscard]] std::string Transcript() const {
    std::string text;
    for (const auto& l : lines) text += "  | " + l + "\n";
    return text;
  }
  [[nodiscard]] bool Printed(const std::string& prefix) const {
    return std::any_of(lines.begin(), lines.end(),
                       [&](const std::string& l) { return l.starts_with(prefix); });
  }
};

class DdsSecurity : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string pattern = (fs::temp_directory_path() / "autodrive_dds_security_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    keystore_ = dir_ / "keystore";
    const ToolResult made = RunKeystoreTool({"city", keystore_.string(), "--operators", "alice,bob",
                                             "--viewers", "carol", "--infra", "lights1"});
    ASSERT_EQ(made.exit_code, 0) << made.output;
    ready_ = true;
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void SetUp() override { ASSERT_TRUE(ready_) << "the keystore could not be made"; }

  static std::string Partition(const char* test) {
    return std::string("security_") + test + "_" + std::to_string(::getpid());
  }

  // Joins in this process as `enclave` ("" = unsecured, whatever the environment says).
  static dds::Participant Join(const std::string& partition, const std::string& enclave) {
    dds::ParticipantOptions options;
    options.partition = partition;
    options.security = enclave.empty() ? dds::SecurityOptions{}
                                       : dds::SecurityOptions::Enforced(keystore_, enclave);
    return dds::Participant(options);
  }

  // Starts dds_test_peer MODE PARTITION as `enclave` ("" = unsecured) on `topic`.
  static Peer StartPeer(const std::string& mode, const std::string& partition,
                        const std::string& enclave, const std::string& topic,
                        const std::string& type, std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{
        ExecutableDir() + "/dds_test_peer", mode, partition, "--topic", topic, "--type", type};
    // Whatever the developer's shell says (ROS_SECURITY_*), the arguments decide.
    if (enclave.empty()) {
      argv.emplace_back("--unsecured");
    } else {
      argv.insert(argv.end(), {"--keystore", keystore_.string(), "--enclave", enclave});
    }
    argv.insert(argv.end(), extra.begin(), extra.end());
    return Peer{ChildProcess(argv), {}};
  }

  static inline fs::path dir_;
  static inline fs::path keystore_;
  static inline bool ready_ = false;
};

// (a) The one path that must work: the SCM's light command reaches the light's host.
TEST_F(DdsSecurity, ScmCommandReachesTheLightHostInAnotherProcess) {
  const std::string partition = Partition("scm_to_light");
  auto p = Join(partition, kLights);
  ASSERT_TRUE(p.secured());
  EXPECT_EQ(p.enclave(), kLights);
  dds::Reader<msg::Int32> reader(p, kLightCommand, dds::Qos::LatchedState());

  Peer scm = StartPeer("write", partition, kScm, kLightCommand, "int32", {"--value", "3"});
  ASSERT_EQ(scm.Await("joined"), std::string("joined secured ") + kScm) << scm.Transcript();
  ASSERT_EQ(scm.Await("created"), "created") << scm.Transcript();
  ASSERT_TRUE(reader.WaitForData(30s)) << scm.Transcript();
  auto got = reader.TakeOne();
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ((*got)->data, 3);
  EXPECT_EQ(reader.matched_writers(), 1u);
  EXPECT_EQ(scm.Await("written"), "written") << scm.Transcript();
  EXPECT_EQ(scm.Finish(), 0) << scm.Transcript();
}

// (b) Operators and viewers command the SCM, never a light: their writers are refused here, in
// this process, with a DdsError naming the topic; and the light's host hears only the SCM.
TEST_F(DdsSecurity, OperatorsAndViewersCannotCommandALight) {
  const std::string partition = Partition("operator_to_light");
  Peer light = StartPeer("read", partition, kLights, kLightCommand, "int32");
  ASSERT_EQ(light.Await("ready"), "ready") << light.Transcript();

  for (const char* enclave : {kAlice, kCarol}) {
    SCOPED_TRACE(enclave);
    auto p = Join(partition, enclave);
    ASSERT_TRUE(p.secured());
    try {
      dds::Writer<msg::Int32> writer(p, kLightCommand, dds::Qos::LatchedState());
      ADD_FAILURE() << enclave << " could create a writer on " << kLightCommand;
      writer.Write(msg::Int32{99});
    } catch (const DdsError& e) {
      EXPECT_EQ(e.code(), DDS_RETCODE_NOT_ALLOWED_BY_SECURITY) << e.what();
      EXPECT_NE(std::string(e.what()).find(kLightCommand), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("DDS Security permissions do not allow it"),
                std::string::npos)
          << e.what();
    }
    // Nor can they pretend to be the light: they may read its state, not write it (refused at
    // the writer, since the topic itself is one they may use).
    const std::string error = test::ErrorMessage<DdsError>(
        [&] { dds::Writer<msg::Int32> writer(p, kLightState, dds::Qos::LatchedState()); });
    EXPECT_NE(error.find(std::string("dds_create_writer(") + kLightState), std::string::npos)
        << error;
  }

  // The control: the SCM's command does arrive, and it is all that arrives (no operator or
  // viewer ever had a writer, so nothing can come later).
  Peer scm = StartPeer("write", partition, kScm, kLightCommand, "int32", {"--value", "3"});
  ASSERT_TRUE(light.Await("got", 30s)) << light.Transcript() << scm.Transcript();
  EXPECT_EQ(light.lines.back(), "got 3");
  EXPECT_EQ(scm.Await("written"), "written") << scm.Transcript();
  EXPECT_EQ(scm.Finish(), 0);
  EXPECT_EQ(light.Finish(), 0);
  for (const auto& line : light.lines) {
    EXPECT_TRUE(!line.starts_with("got") || line == "got 3") << light.Transcript();
    EXPECT_TRUE(!line.starts_with("matched") || line == "matched 1" || line == "matched 0")
        << light.Transcript();
  }
}

// (c) A participant without an identity takes no part: its writer matches no secured reader
// and delivers nothing, and its reader matches no secured writer.
TEST_F(DdsSecurity, AnUnauthenticatedParticipantNeitherMatchesNorReceivesNorDelivers) {
  const std::string partition = Partition("unauthenticated");
  auto p = Join(partition, kLights);
  dds::Reader<msg::Int32> reader(p, kLightCommand, dds::Qos::LatchedState());

  // The SCM commands light 1 (for the secured reader here) and light 2 (no secured reader:
  // bait for the eavesdropper below; latched, so a late match would still deliver it).
  Peer scm = StartPeer("write", partition, kScm, kLightCommand, "int32", {"--value", "3"});
  Peer scm_bait = StartPeer("write", partition, kScm, kLight2Command, "int32",
                            {"--value", "4", "--match-timeout-ms", "1"});
  // The control: the secured SCM reaches the secured light, so discovery, authentication and
  // matching all work on this machine.
  ASSERT_TRUE(reader.WaitForData(30s)) << scm.Transcript();
  ASSERT_EQ(reader.TakeOne().value()->data, 3);
  ASSERT_EQ(scm_bait.Await("written"), "written") << scm_bait.Transcript();

  // Absence of a match has no event to wait for, so here is the one bounded wait: the rogue
  // writer waits up to 3 s for a reader of light 1's command (unauthenticated discovery needs
  // no handshake and takes milliseconds on loopback), then writes anyway, latched, so that a
  // late match would still deliver it. The eavesdropper listens to light 2 in the same window.
  Peer eavesdropper = StartPeer("read", partition, "", kLight2Command, "int32");
  ASSERT_EQ(eavesdropper.Await("joined"), "joined unsecured") << eavesdropper.Transcript();
  ASSERT_EQ(eavesdropper.Await("ready"), "ready") << eavesdropper.Transcript();
  Peer rogue = StartPeer("write", partition, "", kLightCommand, "int32",
                         {"--value", "66", "--match-timeout-ms", "3000"});
  ASSERT_EQ(rogue.Await("joined"), "joined unsecured") << rogue.Transcript();
  EXPECT_EQ(rogue.Await("created"), "created") << rogue.Transcript();
  EXPECT_EQ(rogue.Await("", 30s), "unmatched") << rogue.Transcript();  // not "matched N"
  EXPECT_EQ(rogue.Await("written"), "written") << rogue.Transcript();

  EXPECT_EQ(reader.matched_writers(), 1u) << "only the SCM";
  dds::Message<msg::Int32> m;
  EXPECT_FALSE(reader.TakeOne(m)) << "received " << m->data << " from an unauthenticated writer";
  EXPECT_EQ(rogue.Finish(), 0);
  EXPECT_EQ(eavesdropper.Finish(), 0);
  EXPECT_FALSE(eavesdropper.Printed("matched")) << eavesdropper.Transcript();
  EXPECT_FALSE(eavesdropper.Printed("got")) << eavesdropper.Transcript();
  EXPECT_EQ(scm.Finish(), 0);
  EXPECT_EQ(scm_bait.Finish(), 0);
}

// (d) An operator has its own request topic; nobody else may publish on it.
TEST_F(DdsSecurity, OperatorsPublishOnTheirOwnRequestTopicOnly) {
  const std::string partition = Partition("operator_topics");
  auto p = Join(partition, kScm);
  dds::Reader<msg::OperatorRequest> alice_topic(p, kAliceRequest, dds::Qos::Command());
  dds::Reader<msg::OperatorRequest> shared_topic(p, kSharedRequest, dds::Qos::Command());

  Peer alice =
      StartPeer("write", partition, kAlice, kAliceRequest, "operator_request", {"--value", "7"});
  ASSERT_TRUE(alice_topic.WaitForData(30s)) << alice.Transcript();
  EXPECT_EQ(alice_topic.TakeOne().value()->request_id, 7u);

  Peer alice_as_bob =
      StartPeer("write", partition, kAlice, kBobRequest, "operator_request", {"--value", "8"});
  const auto refused = alice_as_bob.Await("refused");
  ASSERT_TRUE(refused) << alice_as_bob.Transcript();
  // Alice may neither write nor read Bob's topic, so even the topic is refused.
  EXPECT_NE(refused->find(std::string("dds_create_topic(") + kBobRequest), std::string::npos)
      << *refused;
  EXPECT_NE(refused->find("DDS Security permissions do not allow it"), std::string::npos)
      << *refused;

  Peer carol_as_alice =
      StartPeer("write", partition, kCarol, kAliceRequest, "operator_request", {"--value", "9"});
  ASSERT_TRUE(carol_as_alice.Await("refused")) << carol_as_alice.Transcript();

  // The control: the viewer may ask on the shared topic, and the SCM gets it.
  Peer carol =
      StartPeer("write", partition, kCarol, kSharedRequest, "operator_request", {"--value", "10"});
  ASSERT_TRUE(shared_topic.WaitForData(30s)) << carol.Transcript();
  EXPECT_EQ(shared_topic.TakeOne().value()->request_id, 10u);

  EXPECT_EQ(alice_as_bob.Finish(), 3) << "refused";
  EXPECT_EQ(carol_as_alice.Finish(), 3) << "refused";
  EXPECT_EQ(alice.Finish(), 0);
  EXPECT_EQ(carol.Finish(), 0);
  // Nothing but Alice's own request reached her topic (the others never had a writer).
  EXPECT_FALSE(alice_topic.TakeOne().has_value());
}

// ---- The participant's security settings -------------------------------------------------------

TEST_F(DdsSecurity, EnforcedSecurityWithoutAKeystoreSaysSo) {
  dds::ParticipantOptions options;
  options.security = dds::SecurityOptions::Enforced("", kScm);
  const std::string error = test::ErrorMessage([&] { dds::Participant p(options); });
  EXPECT_NE(error.find("no keystore"), std::string::npos) << error;
  EXPECT_NE(error.find("ROS_SECURITY_KEYSTORE"), std::string::npos) << error;
}

TEST_F(DdsSecurity, AMissingEnclaveFileIsAnInputErrorNamingTheFile) {
  const fs::path broken = dir_ / "broken_keystore";
  const fs::path enclave_dir = broken / "enclaves/autodrive/operator/alice";
  fs::create_directories(enclave_dir);
  fs::copy(keystore_ / "enclaves/autodrive/operator/alice", enclave_dir,
           fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  fs::remove(enclave_dir / "permissions.p7s");
  dds::ParticipantOptions options;
  options.security = dds::SecurityOptions::Enforced(broken.string(), kAlice);
  const std::string error = test::ErrorMessage([&] { dds::Participant p(options); });
  EXPECT_NE(error.find((enclave_dir / "permissions.p7s").string() + " is missing"),
            std::string::npos)
      << error;
  EXPECT_EQ(error.find("key.pem"), std::string::npos) << "only the missing file: " << error;

  // Permissive does not paper over a broken enclave either.
  options.security->strategy = dds::SecurityStrategy::kPermissive;
  EXPECT_NE(test::ErrorMessage([&] { dds::Participant p(options); }).find("permissions.p7s"),
            std::string::npos);
}

TEST_F(DdsSecurity, AnAbsentEnclaveIsAnErrorWhenEnforcedAndUnsecuredWhenPermissive) {
  dds::ParticipantOptions options;
  options.security = dds::SecurityOptions::Enforced(keystore_.string(), "/autodrive/nobody");
  const std::string error = test::ErrorMessage([&] { dds::Participant p(options); });
  EXPECT_NE(error.find("has no enclave /autodrive/nobody"), std::string::npos) << error;

  options.security->strategy = dds::SecurityStrategy::kPermissive;
  dds::Participant p(options);
  EXPECT_FALSE(p.secured());
}

TEST_F(DdsSecurity, AnEnclaveNameCannotLeaveTheKeystore) {
  for (const char* bad : {"/../private", "autodrive/scm", "/autodrive//scm", "/autodrive/scm/"}) {
    dds::ParticipantOptions options;
    options.security = dds::SecurityOptions::Enforced(keystore_.string(), bad);
    const std::string error = test::ErrorMessage([&] { dds::Participant p(options); });
    EXPECT_NE(error.find(std::string("enclave '") + bad + "' is not an absolute ROS name"),
              std::string::npos)
        << error;
  }
}

// Permissions are public documents; what binds them to an identity is the subject name, checked
// against the certificate. Alice's key with the SCM's permissions must not make her the SCM.
TEST_F(DdsSecurity, AnIdentityCannotBorrowAnotherEnclavesPermissions) {
  const fs::path forged = dir_ / "forged_keystore";
  const fs::path enclave_dir = forged / "enclaves/autodrive/scm";
  fs::create_directories(enclave_dir);
  fs::copy(keystore_ / "enclaves/autodrive/scm", enclave_dir,
           fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  dds::ParticipantOptions options;
  options.security = dds::SecurityOptions::Enforced(forged.string(), kScm);
  EXPECT_TRUE(dds::Participant(options).secured()) << "the copy itself works";
  for (const char* file : {"cert.pem", "key.pem"}) {
    fs::copy_file(keystore_ / "enclaves/autodrive/operator/alice" / file, enclave_dir / file,
                  fs::copy_options::overwrite_existing);
  }
  const std::string error = test::ErrorMessage<DdsError>([&] { dds::Participant p(options); });
  EXPECT_NE(error.find("dds_create_participant with DDS Security (enclave /autodrive/scm"),
            std::string::npos)
      << error;
}

TEST_F(DdsSecurity, SettingsComeFromTheEnvironmentAsInRos2) {
  ::setenv("ROS_SECURITY_ENABLE", "true", 1);
  ::setenv("ROS_SECURITY_STRATEGY", "Enforce", 1);
  ::setenv("ROS_SECURITY_KEYSTORE", keystore_.c_str(), 1);
  ::setenv("ROS_SECURITY_ENCLAVE_OVERRIDE", kLights, 1);
  ::setenv("ROS_SECURITY_ENCLAVE", kScm, 1);
  const auto options = dds::SecurityOptions::FromEnvironment();
  EXPECT_TRUE(options.enabled);
  EXPECT_EQ(options.strategy, dds::SecurityStrategy::kEnforce);
  EXPECT_EQ(options.keystore, keystore_.string());
  EXPECT_EQ(options.enclave, kLights) << "ROS 2's override comes first";
  {
    dds::ParticipantOptions unset;  // no security set: the environment decides
    dds::Participant p(unset);
    EXPECT_TRUE(p.secured());
    EXPECT_EQ(p.enclave(), kLights);
  }
  ::unsetenv("ROS_SECURITY_ENCLAVE_OVERRIDE");
  EXPECT_EQ(dds::SecurityOptions::FromEnvironment().enclave, kScm);
  ::setenv("ROS_SECURITY_ENABLE", "1", 1);  // ROS 2 enables on "true" only
  ::setenv("ROS_SECURITY_STRATEGY", "enforce", 1);
  const auto off = dds::SecurityOptions::FromEnvironment();
  EXPECT_FALSE(off.enabled);
  EXPECT_EQ(off.strategy, dds::SecurityStrategy::kPermissive);
  for (const char* name : {"ROS_SECURITY_ENABLE", "ROS_SECURITY_STRATEGY", "ROS_SECURITY_KEYSTORE",
                           "ROS_SECURITY_ENCLAVE"}) {
    ::unsetenv(name);
  }
  dds::Participant unsecured{dds::ParticipantOptions{}};
  EXPECT_FALSE(unsecured.secured());
}

// Cyclone DDS cannot serve both kinds in one domain of one process (a secured participant makes
// an unsecured one fail; an unsecured one stops matching once a secured one exists): refused
// up front, in either order, and fine again in another domain or once the other kind is gone.
TEST_F(DdsSecurity, OneProcessCannotMixSecuredAndUnsecuredParticipantsInOneDomain) {
  const std::string partition = Partition("mixed");
  {
    auto secured = Join(partition, kScm);
    const std::string error = test::ErrorMessage([&] { Join(partition, ""); });
    EXPECT_NE(error.find("already has 1 secured participant(s) in DDS domain " +
                         std::to_string(secured.domain_id())),
              std::string::npos)
        << error;
    dds::ParticipantOptions elsewhere;
    elsewhere.domain_id = (secured.domain_id() + 1) % 231;
    elsewhere.security = dds::SecurityOptions{};
    EXPECT_FALSE(dds::Participant(elsewhere).secured());
  }
  {
    auto unsecured = Join(partition, "");
    EXPECT_NE(test::ErrorMessage([&] {
                Join(partition, kScm);
              }).find("already has 1 unsecured participant(s)"),
              std::string::npos);
  }
  EXPECT_TRUE(Join(partition, kScm).secured());
}

TEST_F(DdsSecurity, ThePluginsAreFoundBesideCycloneOrWhereTold) {
  const fs::path dir = dds::SecurityPluginDirectory();
  EXPECT_TRUE(fs::exists(dir / "libdds_security_auth.so")) << dir;
  ::setenv("AUTODRIVE_DDS_SECURITY_PLUGINS", "/nonexistent/plugins", 1);
  const std::string error = test::ErrorMessage([] { (void)dds::SecurityPluginDirectory(); });
  ::unsetenv("AUTODRIVE_DDS_SECURITY_PLUGINS");
  EXPECT_NE(error.find("not in /nonexistent/plugins"), std::string::npos) << error;
  EXPECT_NE(error.find("libddsc0debian"), std::string::npos) << error;
}

// ---- The keystore tool
// ---------------------------------------------------------------------------

TEST_F(DdsSecurity, TheKeystoreToolIsIdempotentAndNeverReplacesACa) {
  const fs::path scm_cert = keystore_ / "enclaves/autodrive/scm/cert.pem";
  const fs::path ca_cert = keystore_ / "public/identity_ca.cert.pem";
  const std::string cert_before = ReadFile(scm_cert);
  const std::string ca_before = ReadFile(ca_cert);
  const ToolResult again = RunKeystoreTool({"city", keystore_.string(), "--operators", "alice,bob",
                                            "--viewers", "carol", "--infra", "lights1"});
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("enclave /autodrive/scm is up to date"), std::string::npos)
      << again.output;
  EXPECT_EQ(again.output.find("created"), std::string::npos) << again.output;
  EXPECT_EQ(ReadFile(scm_cert), cert_before);
  EXPECT_EQ(ReadFile(ca_cert), ca_before);

  // Half a CA: refuse, name the files, and change nothing.
  const fs::path half = dir_ / "half_keystore";
  fs::create_directories(half / "public");
  fs::copy_file(ca_cert, half / "public/identity_ca.cert.pem");
  const ToolResult refused = RunKeystoreTool({"init", half.string()});
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.output.find("incomplete identity CA"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find((half / "private/identity_ca.key.pem").string() + " is missing"),
            std::string::npos)
      << refused.output;
  EXPECT_EQ(ReadFile(half / "public/identity_ca.cert.pem"), ca_before);

  const ToolResult roles = RunKeystoreTool({"roles"});
  EXPECT_EQ(roles.exit_code, 0) << roles.output;
  EXPECT_NE(roles.output.find("operator  publish    rt/autodrive/scm/operator/NAME/request"),
            std::string::npos)
      << roles.output;

  const ToolResult no_role =
      RunKeystoreTool({"enclave", keystore_.string(), "/autodrive/x", "--role", "admin"});
  EXPECT_NE(no_role.exit_code, 0);
  EXPECT_NE(no_role.output.find("unknown role 'admin'"), std::string::npos) << no_role.output;
}

// The secured lab with the real programs: autodrive-infra and autodrive-scm with their
// identities, scmctl as an operator the city allows (alice), as one it does not (bob, who has
// a DDS identity and his own request topic), and as a viewer borrowing alice's name (carol).
// A participant without the SCM's identity cannot make a light change its lamps, and the light
// host's identity cannot forge the SCM's heartbeat (its own goes on the device hosts' topic,
// where the launcher's identity hears it).
TEST_F(DdsSecurity, TheSecuredLabRunsAndOnlyItsScmCommandsTheLights) {
  const std::string partition = Partition("secured_lab");
  const fs::path dir = dir_ / partition;
  fs::create_directories(dir);
  // The Driving School, allowing the operator alice only (its map named by absolute path).
  std::string city = ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
  city.replace(city.find("../maps/driving_school.yaml"), 27,
               (test::SourceDir() / "config/maps/driving_school.yaml").string());
  city.replace(city.find("operators: {allowed: [lab]}"), 27, "operators: {allowed: [alice]}");
  const fs::path city_file = dir / "city.yaml";
  std::ofstream(city_file) << city;
  const std::string bin = ExecutableDir() + "/";
  const std::vector<std::string> secured{"--keystore", keystore_.string()};
  const auto argv = [&](std::vector<std::string> a, const std::vector<std::string>& more) {
    a.insert(a.end(), secured.begin(), secured.end());
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  ChildProcess infra(argv({bin + "autodrive-infra", "--config",
                           (test::SourceDir() / "config/infra/driving_school.yaml").string(),
                           "--partition", partition, "--log-level", "warn"},
                          {"--enclave", kLights}));
  ChildProcess scm(argv({bin + "autodrive-scm", "--config", city_file.string(), "--partition",
                         partition, "--db", (dir / "scm.db").string(), "--log-level", "warn"},
                        {}));
  const auto scmctl = [&](std::vector<std::string> args, const std::vector<std::string>& as) {
    std::vector<std::string> a{"/bin/sh",      "-c",          "exec \"$0\" \"$@\" 2>&1",
                               bin + "scmctl", "--partition", partition,
                               "--timeout",    "20"};
    a.insert(a.end(), secured.begin(), secured.end());
    a.insert(a.end(), as.begin(), as.end());
    a.insert(a.end(), args.begin(), args.end());
    ChildProcess p(a);
    ToolResult r;
    while (auto line = p.ReadLine(60s)) r.output += *line + "\n";
    r.exit_code = p.Wait(60s).value_or(-1);
    return r;
  };
  // This process watches as the viewer carol: SPaT and the lamps.
  auto viewer = Join(partition, kCarol);
  dds::Reader<msg::Spat> spat(viewer, dds::topics::Spat());
  dds::Reader<msg::Int32> lamp1(viewer, dds::topics::SignalState(SignalHeadId(1)));
  const auto wait_spat = [&](auto pred) {
    for (const auto end = std::chrono::steady_clock::now() + 60s;
         std::chrono::steady_clock::now() < end;) {
      spat.WaitForData(100ms);
      for (auto& m : spat.TakeAll()) {
        if (pred(*m)) return true;
      }
    }
    return false;
  };
  const auto any_green = [](const msg::Spat& m) {
    for (const auto& x : dds::Elements(m.intersections)) {
      for (const auto& g : dds::Elements(x.signal_groups)) {
        if (g.event_state == 6) return true;  // protected movement allowed
      }
    }
    return false;
  };
  ASSERT_TRUE(wait_spat(any_green)) << "the secured SCM and lights run the plan";
  // Each heartbeat on its own topic, both heard by the launcher's identity.
  Peer scm_beats = StartPeer("read", partition, kLauncher, kScmHeartbeat, "heartbeat");
  Peer infra_beats = StartPeer("read", partition, kLauncher, kInfraHeartbeat, "heartbeat");
  EXPECT_EQ(scm_beats.Await("got"), "got scm") << scm_beats.Transcript();
  EXPECT_EQ(infra_beats.Await("got"), "got infra/driving_school_lights")
      << infra_beats.Transcript();
  // The light host's identity cannot write the SCM's heartbeat (a forged one made every head
  // flash and latched the city before the device hosts had a topic of their own).
  Peer forger =
      StartPeer("write", partition, kLights, kScmHeartbeat, "heartbeat", {"--value", "1"});
  const auto forged = forger.Await("refused");
  ASSERT_TRUE(forged) << forger.Transcript();
  EXPECT_NE(forged->find(std::string("dds_create_writer(") + kScmHeartbeat), std::string::npos)
      << *forged;
  EXPECT_NE(forged->find("DDS Security permissions do not allow it"), std::string::npos) << *forged;
  EXPECT_EQ(forger.Finish(), 3) << forger.Transcript();
  EXPECT_EQ(scm_beats.Finish(), 0) << scm_beats.Transcript();
  EXPECT_EQ(infra_beats.Finish(), 0) << infra_beats.Transcript();
  for (const auto& line : scm_beats.lines) {
    EXPECT_TRUE(!line.starts_with("got") || line == "got scm") << scm_beats.Transcript();
  }
  // The viewer cannot command a light: no writer can be created.
  EXPECT_THROW(
      {
        dds::Writer<msg::Int32> w(viewer, dds::topics::SignalCommand(SignalHeadId(1)).name,
                                  dds::Qos::LatchedState());
      },
      DdsError);
  // Nor can an operator, from another process: alice's identity is refused the writer too.
  Peer rogue = StartPeer("write", partition, kAlice, "rt/autodrive/signal_1/command", "int32",
                         {"--value", "3"});
  rogue.Finish();
  EXPECT_FALSE(rogue.Printed("written")) << rogue.Transcript();
  // alice changes the mode; bob (a DDS operator the city does not allow) and carol (a viewer,
  // with no writer on alice's topic) cannot.
  auto r = scmctl({"mode", "driving_school_crossing", "manual"}, {"--operator", "bob"});
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("may not change state"), std::string::npos) << r.output;
  r = scmctl({"mode", "driving_school_crossing", "manual"},
             {"--operator", "alice", "--enclave", kCarol});
  EXPECT_NE(r.exit_code, 0) << r.output;
  r = scmctl({"show", "driving_school_crossing"}, {"--enclave", kCarol});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("requested=auto"), std::string::npos) << r.output;
  r = scmctl({"mode", "driving_school_crossing", "manual"}, {"--operator", "alice"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = scmctl({"show", "driving_school_crossing"}, {"--operator", "alice"});
  EXPECT_NE(r.output.find("mode=manual"), std::string::npos) << r.output;
  // The lamps follow the SCM: signal_1 reports states (the secured light host publishes them).
  EXPECT_TRUE(lamp1.WaitForData(30s));
  EXPECT_EQ(scm.Stop(10s), 0);
  EXPECT_EQ(infra.Stop(10s), 0);
}

}  // namespace
}  // namespace autodrive
