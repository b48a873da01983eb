#pragma once
/// @file
/// Helpers shared by the project's GoogleTest tests. Include only from tests.

#include <gtest/gtest.h>

#include <charconv>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

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

/// The repository root (AUTODRIVE_SOURCE_DIR, which CTest sets). Throws when unset.
inline std::filesystem::path SourceDir() {
  const char* src = std::getenv("AUTODRIVE_SOURCE_DIR");
  if (src == nullptr || *src == '\0') {
    throw std::runtime_error("AUTODRIVE_SOURCE_DIR is not set (run the test through ctest)");
  }
  return src;
}

}  // namespace autodrive::test
