#pragma once
/// @file
/// What the tests that run `autodrive-scm-nema` as a program share (libsumo runs one
/// simulation per process, so each SUMO run is a child process).

#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "common/process.h"
#include "common/test_support.h"

namespace autodrive::traffic::nema::support {

/// The Driving School's city file.
inline std::string DrivingSchool() {
  return (test::SourceDir() / "config/cities/driving_school.yaml").string();
}

/// What a run printed and how it ended.
struct Output {
  int code = -1;
  std::string text;  ///< stdout and stderr
};

/// Runs autodrive-scm-nema with `args`, waiting up to `timeout` for its output.
inline Output RunNema(const std::vector<std::string>& args,
                      std::chrono::minutes timeout = std::chrono::minutes(10)) {
  const char* bin = std::getenv("AUTODRIVE_BINARY_DIR");
  std::vector<std::string> argv = {
      "/bin/sh", "-c", "exec \"$0\" \"$@\" 2>&1",
      std::string(bin != nullptr ? bin : ".") + "/bin/autodrive-scm-nema"};
  argv.insert(argv.end(), args.begin(), args.end());
  Output out;
  ChildProcess child(argv);
  child.CloseStdin();
  while (auto line = child.ReadLine(timeout)) out.text += *line + "\n";
  const std::optional<int> rc = child.Wait(std::chrono::seconds(30));
  out.code = rc ? *rc : child.Stop();
  return out;
}

}  // namespace autodrive::traffic::nema::support
