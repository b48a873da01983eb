#pragma once
/// @file
/// Text files, command lines and times of day as the crosscheck's and the oracle's runs write
/// them (not part of traffic/nema's API).

#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/time.h"

namespace autodrive::traffic::nema::internal {

/// Writes `text` to `path` (replaced). Throws `InputError` naming the path when it cannot.
inline void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  AUTODRIVE_THROW_UNLESS(!out.fail(), "cannot write " << path.string());
}

/// The text of `path` (empty when it cannot be read).
inline std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// `argv` as a shell command line: words with spaces or quotes in single quotes.
inline std::string Quoted(const std::vector<std::string>& argv) {
  std::string out;
  for (const std::string& a : argv) {
    const bool plain = !a.empty() && a.find_first_of(" \t\"'$\\") == std::string::npos;
    out += (out.empty() ? "" : " ") + (plain ? a : "'" + a + "'");
  }
  return out;
}

/// A time since midnight as "HH:MM" (whole minutes, rounded down).
inline std::string HoursMinutes(Duration since_midnight) {
  const auto minutes = std::chrono::duration_cast<std::chrono::minutes>(since_midnight).count();
  return fmt::format("{:02}:{:02}", minutes / 60, minutes % 60);
}

}  // namespace autodrive::traffic::nema::internal
