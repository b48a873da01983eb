#pragma once
/// @file
/// Helpers shared by the project's GoogleTest tests. Include only from tests.

#include <gtest/gtest.h>
#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>

#include "common/error.h"

namespace autodrive::test {

/// Runs `f`, expects it to throw `E`, and returns the exception's message; "" and a test
/// failure when it does not throw `E`.
template <typename E = InputError, typename F>
std::string ErrorMessage(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an exception";
  return "";
}

/// The factor randomised cross-checks multiply their case counts by: AUTODRIVE_SOAK_FACTOR
/// when set (a positive integer; anything else is a test failure), else 1.
inline int SoakFactor() {
  const char* text = std::getenv("AUTODRIVE_SOAK_FACTOR");
  if (text == nullptr || *text == '\0') {
    return 1;
  }
  int factor = 0;
  const char* end = text + std::strlen(text);
  const auto [ptr, ec] = std::from_chars(text, end, factor);
  if (ec != std::errc() || ptr != end || factor < 1) {
    ADD_FAILURE() << "AUTODRIVE_SOAK_FACTOR must be a positive integer, got \"" << text << "\"";
    return 1;
  }
  return factor;
}

/// How many cases a randomised cross-check of `base` cases runs: `base` times `SoakFactor()`,
/// times AUTODRIVE_CASES_PERCENT / 100 when that is set (an integer 1..100; anything else is a
/// test failure). The sanitizer legs of CI set it: under a sanitizer a case costs 20 to 50
/// times more, and a share of the cases finds memory and race errors in the same code paths
/// while the full count runs in the plain build. At least one case.
inline int Cases(int base) {
  int cases = base * SoakFactor();
  const char* text = std::getenv("AUTODRIVE_CASES_PERCENT");
  if (text == nullptr || *text == '\0') return cases;
  int percent = 0;
  const char* end = text + std::strlen(text);
  const auto [ptr, ec] = std::from_chars(text, end, percent);
  if (ec != std::errc() || ptr != end || percent < 1 || percent > 100) {
    ADD_FAILURE() << "AUTODRIVE_CASES_PERCENT must be an integer from 1 to 100, got \"" << text
                  << "\"";
    return cases;
  }
  cases = static_cast<int>(static_cast<long long>(cases) * percent / 100);
  return cases < 1 ? 1 : cases;
}

/// The repository root (AUTODRIVE_SOURCE_DIR, which CTest sets). Throws when unset.
inline std::filesystem::path SourceDir() {
  const char* src = std::getenv("AUTODRIVE_SOURCE_DIR");
  if (src == nullptr || *src == '\0') {
    throw std::runtime_error("AUTODRIVE_SOURCE_DIR is not set (run the test through ctest)");
  }
  return src;
}

/// A fresh, empty directory for one test's files, `<temp>/<prefix>_<pid>_<test name>`, removed
/// at the end when the test passed (kept for inspection when it failed).
class TempDir {
 public:
  explicit TempDir(std::string_view prefix) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            (std::string(prefix) + "_" + std::to_string(::getpid()) + "_" + info->name());
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    if (!::testing::Test::HasFailure()) std::filesystem::remove_all(path_);
  }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] std::string str() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace autodrive::test
