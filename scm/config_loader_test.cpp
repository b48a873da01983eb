#include "scm/config_loader.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>

#include "common/config.h"
#include "common/dds/participant.h"
#include "common/test_support.h"

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
    loader_ = std::make_unique<ConfigLoader>(
        *participant_, *store_,
        MapResolution{test::SourceDir() / "config/cities", test::SourceDir()},
        [this] { woken_ = true; });
    yaml_ = config::internal::ReadFile(test::SourceDir() / "config/cities/driving_school.yaml");
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
  loader_->Check(yaml_, "driving_school.yaml", [&](std::unique_ptr<City> city, std::string error) {
    EXPECT_TRUE(city) << error;
    busy_in_answer = loader_->busy();
    first = true;
  });
  EXPECT_TRUE(loader_->busy());
  ASSERT_TRUE(RunUntil(first));
  EXPECT_TRUE(woken_.load());
  EXPECT_FALSE(busy_in_answer);
  EXPECT_FALSE(loader_->busy());
  std::unique_ptr<CityBundle> built;
  loader_->Build(yaml_, "driving_school.yaml", 2,
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

TEST_F(ConfigLoaderTest, ABrokenConfigurationIsAnsweredWithItsErrorAndEndsTheRequest) {
  std::atomic<bool> done{false};
  std::string got;
  loader_->Check("name: broken\nmap: nowhere.yaml\n", "broken.yaml",
                 [&](std::unique_ptr<City> city, std::string error) {
                   EXPECT_FALSE(city);
                   got = std::move(error);
                   done = true;
                 });
  ASSERT_TRUE(RunUntil(done));
  EXPECT_NE(got.find("broken.yaml"), std::string::npos) << got;
  EXPECT_FALSE(loader_->busy());
}

}  // namespace
}  // namespace autodrive::scm
