#include "scm/config_loader.h"

#include <gtest/gtest.h>
#include <malloc.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>

#include "common/config.h"
#include "common/dds/participant.h"
#include "common/test_support.h"
#include "scm/benchmarks/bench_support.h"

namespace autodrive::scm {
namespace {

using std::chrono::seconds;

class ConfigLoaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    partition_ = "scm_loader_" + std::to_string(::getpid()) + "_" + info->name();
    dir_ = std::filesystem::temp_directory_path() / partition_;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    participant_ = std::make_unique<dds::Participant>(dds::ParticipantOptions{{}, partition_, {}});
    store_ = std::make_unique<Store>((dir_ / "scm.db").string());
    writers_ = std::make_unique<SignalCommandWriters>(*participant_);
    loader_ = std::make_unique<ConfigLoader>(
        *participant_, ClockKind::kWall, *writers_, *store_,
        MapResolution{test::SourceDir() / "config/cities", test::SourceDir()}, "",
        [this] { woken_ = true; });
    yaml_ = config::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
  }
  void TearDown() override {
    loader_.reset();
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  /// Runs the loader's completions until `done` holds, or 60 s pass.
  bool RunUntil(const std::atomic<bool>& done) {
    for (const auto end = std::chrono::steady_clock::now() + seconds(60);
         std::chrono::steady_clock::now() < end;) {
      loader_->RunCompletions();
      if (done) return true;
      std::this_thread::yield();
    }
    return false;
  }

  std::string partition_;
  std::filesystem::path dir_;
  std::unique_ptr<dds::Participant> participant_;
  std::unique_ptr<Store> store_;
  std::unique_ptr<SignalCommandWriters> writers_;
  std::unique_ptr<ConfigLoader> loader_;
  std::atomic<bool> woken_{false};
  std::string yaml_;
};

// The SCM refuses a configuration request while another is in flight. "In flight" ends when
// the first one's answer is given, not when the loader's thread gets round to noting it: an
// operator who got the answer may send the next one at once (seen as "another configuration is
// being loaded" in CI on a loaded machine).
TEST_F(ConfigLoaderTest, ARequestIsInFlightUntilItsAnswerAndNotAMomentLonger) {
  EXPECT_FALSE(loader_->busy());
  std::atomic<bool> first{false}, second{false};
  bool busy_in_answer = true;
  loader_->Check(yaml_, "driving_school.yaml", {},
                 [&](std::unique_ptr<City> city, std::string error) {
                   EXPECT_TRUE(city) << error;
                   busy_in_answer = loader_->busy();
                   first = true;
                 });
  EXPECT_TRUE(loader_->busy());
  ASSERT_TRUE(RunUntil(first));
  // The loader wakes the loop just after it queues the completion, so a loop already polling
  // may run the completion first (as this one did once, under ASan in CI): wait for the wake.
  EXPECT_TRUE(RunUntil(woken_)) << "the loader never woke the loop";
  EXPECT_FALSE(busy_in_answer);
  EXPECT_FALSE(loader_->busy());
  std::unique_ptr<CityBundle> built;
  loader_->Build(yaml_, "driving_school.yaml", 2, {},
                 [&](std::unique_ptr<CityBundle> bundle, std::string error) {
                   EXPECT_TRUE(bundle) << error;
                   built = std::move(bundle);
                   second = true;
                 });
  EXPECT_TRUE(loader_->busy());
  ASSERT_TRUE(RunUntil(second));
  ASSERT_TRUE(built);
  EXPECT_EQ(built->city().config.name, "driving_school");
  // Disposing of an old city is the loader's housekeeping, not a request: nothing waits on it.
  loader_->Dispose(std::move(built));
  EXPECT_FALSE(loader_->busy());
}

// A city applied again keeps its lights' command writers: the lights stay matched through the
// apply and no DDS writers churn (Cyclone keeps a little of every deleted writer for good, which
// made RSS climb with each apply of a big city). A light no city holds any more loses its writer.
TEST_F(ConfigLoaderTest, ACityBuiltAgainSharesTheLightsWritersOfTheCityItReplaces) {
  auto build = [&](const std::string& yaml) {
    std::atomic<bool> done{false};
    std::unique_ptr<CityBundle> built;
    loader_->Build(yaml, "city.yaml", 2, {},
                   [&](std::unique_ptr<CityBundle> bundle, std::string e) {
                     EXPECT_TRUE(bundle) << e;
                     built = std::move(bundle);
                     done = true;
                   });
    EXPECT_TRUE(RunUntil(done));
    return built;
  };
  auto first = build(yaml_);
  ASSERT_TRUE(first);
  const std::size_t heads = first->runtime->heads().size();
  ASSERT_GT(heads, 0u);
  EXPECT_EQ(writers_->created(), heads);
  auto second = build(yaml_);
  ASSERT_TRUE(second);
  EXPECT_EQ(writers_->created(), heads) << "the second city made writers of its own";
  const SignalHeadId id = first->runtime->heads().front().id;
  std::shared_ptr<SignalCommandWriters::Writer> held = writers_->Acquire(id);
  first.reset();
  EXPECT_EQ(writers_->Acquire(id), held) << "the writer went with the city it was first made for";
  second.reset();
  EXPECT_EQ(held.use_count(), 1) << "a city that is gone still holds the writer";
  const std::weak_ptr<SignalCommandWriters::Writer> gone = held;
  held.reset();
  EXPECT_TRUE(gone.expired()) << "a writer no city holds is kept";
  // Once no city holds them, the lights' writers are made anew.
  auto third = build(yaml_);
  ASSERT_TRUE(third);
  EXPECT_EQ(writers_->created(), 2 * heads);
}

// The SCM applies configurations for weeks: building a city and disposing of the one it replaced
// gives back all that the old one took. A 16 x 16 grid city (1,024 lights) is built six times,
// each replacing the one before; the heap in use after the sixth is that after the second.
// (Cyclone 0.10.2 kept ~380 bytes of every deleted writer, and each apply made a writer per
// light: 1.5 MB over these rounds, 1.6 MB per apply of a 32 x 32 city.)
TEST_F(ConfigLoaderTest, ReplacingACityAgainAndAgainKeepsNothingOfTheOldOnes) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizers' allocators do not report the heap in use";
#else
  const std::filesystem::path grid = bench::WriteGridCity(16, dir_);
  const std::string yaml = config::ReadFile(grid);
  // A domain of its own: participants that other tests and programs on this machine start and
  // stop would otherwise be discovered, and their proxies come and go on this heap.
  loader_.reset();
  writers_.reset();
  participant_ = std::make_unique<dds::Participant>(
      dds::ParticipantOptions{100 + static_cast<std::uint32_t>(::getpid() % 100), partition_, {}});
  writers_ = std::make_unique<SignalCommandWriters>(*participant_);
  loader_ = std::make_unique<ConfigLoader>(*participant_, ClockKind::kWall, *writers_, *store_,
                                           MapResolution{dir_, dir_}, "", nullptr);
  auto build = [&] {
    std::atomic<bool> done{false};
    std::unique_ptr<CityBundle> built;
    loader_->Build(yaml, grid.string(), 2, {},
                   [&](std::unique_ptr<CityBundle> bundle, std::string e) {
                     EXPECT_TRUE(bundle) << e;
                     built = std::move(bundle);
                     done = true;
                   });
    EXPECT_TRUE(RunUntil(done));
    return built;
  };
  // Waits until the loader has disposed of what it was given (its jobs run in order).
  auto settle = [&] {
    std::atomic<bool> done{false};
    loader_->Check("name: x\n", "settle.yaml", {},
                   [&](std::unique_ptr<City>, std::string) { done = true; });
    EXPECT_TRUE(RunUntil(done));
  };
  auto in_use = [] {
    const struct mallinfo2 m = ::mallinfo2();
    return static_cast<double>(m.uordblks + m.hblkhd);
  };
  std::unique_ptr<CityBundle> running = build();
  ASSERT_TRUE(running);
  ASSERT_EQ(running->runtime->heads().size(), 1024u);
  double after_second = 0;
  for (int round = 2; round <= 6; ++round) {
    std::unique_ptr<CityBundle> next = build();
    ASSERT_TRUE(next);
    loader_->Dispose(std::move(running));
    running = std::move(next);
    settle();
    if (round == 2) after_second = in_use();
  }
  const double growth = in_use() - after_second;
  EXPECT_LT(growth, 512e3) << "the heap grew by " << growth / 1e6
                           << " MB over four replacements of a 1,024-light city";
#endif
}

TEST_F(ConfigLoaderTest, ABrokenConfigurationIsAnsweredWithItsErrorAndEndsTheRequest) {
  std::atomic<bool> done{false};
  std::string got;
  loader_->Check("name: broken\nmap: nowhere.yaml\n", "broken.yaml", {},
                 [&](std::unique_ptr<City> city, std::string error) {
                   EXPECT_FALSE(city);
                   got = std::move(error);
                   done = true;
                 });
  ASSERT_TRUE(RunUntil(done));
  EXPECT_NE(got.find("broken.yaml"), std::string::npos) << got;
  EXPECT_FALSE(loader_->busy());
}

// An SCM of one district (docs/districts.md) narrows what it is sent to its district, and refuses
// a configuration without that district.
TEST_F(ConfigLoaderTest, ADistrictsLoaderNarrowsToItsDistrictAndRefusesACityWithoutIt) {
  ConfigLoader uptown(*participant_, ClockKind::kWall, *writers_, *store_,
                      MapResolution{test::SourceDir() / "config/cities", test::SourceDir()},
                      "uptown", [this] { woken_ = true; });
  std::string town = config::ReadFile(test::SourceDir() / "config/cities/small_town.yaml");
  const std::string plain = town;
  town.insert(town.find("\nfleet:") + 1,
              "districts:\n"
              "  - {name: uptown, domain: 11, intersections: [north_t]}\n"
              "  - {name: downtown, domain: 12, intersections: [centre]}\n");
  const auto check = [&](const std::string& text) {
    std::atomic<bool> done{false};
    std::unique_ptr<City> got;
    std::string error;
    uptown.Check(text, "sent.yaml", {}, [&](std::unique_ptr<City> city, std::string e) {
      got = std::move(city);
      error = std::move(e);
      done = true;
    });
    for (const auto end = std::chrono::steady_clock::now() + seconds(60);
         !done && std::chrono::steady_clock::now() < end;) {
      uptown.RunCompletions();
      std::this_thread::yield();
    }
    EXPECT_TRUE(done);
    return std::pair{std::move(got), error};
  };
  const auto [narrowed, no_error] = check(town);
  ASSERT_TRUE(narrowed) << no_error;
  EXPECT_EQ(narrowed->district, "uptown");
  ASSERT_EQ(narrowed->intersections.size(), 1u);
  EXPECT_EQ(narrowed->intersections[0].name, "north_t");
  const auto [refused, error] = check(plain);
  EXPECT_FALSE(refused);
  EXPECT_NE(error.find("city small_town has no district uptown (it has no districts: section)"),
            std::string::npos)
      << error;
}

// Found from outside (issue 30): a city file without `operators:` was validated and applied,
// and from then on every state change, reset included, was refused; applying another city's
// file left every intersection in start-up flash. Both are refused with the reason, and the
// refused city is never built.
TEST_F(ConfigLoaderTest, APolicyRefusesAnotherCityAndACityWithNoOperatorBeforeBuildingIt) {
  const City running = LoadCity(test::SourceDir() / "config/cities/driving_school.yaml");
  const std::vector<std::string> none;
  ASSERT_FALSE(running.config.operators.allowed.empty());
  EXPECT_EQ(ConfigRefusal(running.config, "driving_school", none), std::nullopt);

  CityConfig other = running.config;
  other.name = "small_town";
  const auto refusal = ConfigRefusal(other, "driving_school", none);
  ASSERT_TRUE(refusal);
  EXPECT_NE(refusal->find("the configuration is of city \"small_town\", but this SCM runs city "
                          "\"driving_school\""),
            std::string::npos)
      << *refusal;

  CityConfig locked = running.config;
  locked.operators.allowed.clear();
  const auto lockout = ConfigRefusal(locked, "driving_school", none);
  ASSERT_TRUE(lockout);
  EXPECT_NE(lockout->find("allows no operator to change state"), std::string::npos) << *lockout;
  // An operator of the SCM's own command line is one no configuration takes away.
  const std::vector<std::string> rescue{"rescue"};
  EXPECT_EQ(ConfigRefusal(locked, "driving_school", rescue), std::nullopt);
  EXPECT_EQ(AllowedOperators(locked, rescue), rescue);
  EXPECT_EQ(AllowedOperators(running.config, std::vector<std::string>{"lab", "rescue"}).back(),
            "rescue");

  // Through the loader: the text without its operators section is refused by Check and Build.
  std::string text = yaml_;
  const auto at = text.find("\noperators:");
  ASSERT_NE(at, std::string::npos);
  text = text.substr(0, at + 1);
  ConfigLoader::Policy policy = [none](const City& c) {
    return ConfigRefusal(c.config, "driving_school", none);
  };
  std::atomic<bool> checked{false}, built{false};
  std::string check_error, build_error;
  loader_->Check(text, "locked.yaml", policy, [&](std::unique_ptr<City> city, std::string e) {
    EXPECT_FALSE(city);
    check_error = e;
    checked = true;
  });
  ASSERT_TRUE(RunUntil(checked));
  EXPECT_NE(check_error.find("locked.yaml: the configuration allows no operator"),
            std::string::npos)
      << check_error;
  loader_->Build(text, "locked.yaml", 2, policy, [&](std::unique_ptr<CityBundle> b, std::string e) {
    EXPECT_FALSE(b);
    build_error = e;
    built = true;
  });
  ASSERT_TRUE(RunUntil(built));
  EXPECT_EQ(build_error, check_error);
}

}  // namespace
}  // namespace autodrive::scm
