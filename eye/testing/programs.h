#pragma once
/// @file
/// For the Eye's tests that run the project's programs (`autodrive-eye`, `autodrive-sim`) as
/// processes, as a lab does.

#include <string>
#include <vector>

namespace autodrive::eye::testing {

/// What a program printed (stdout and stderr, in order) and how it ended.
struct ProgramOutput {
  int code = -1;  ///< its exit status; -1 when it did not end within a minute of closing
  std::string text;
};

/// The path of the project's program `name`, beside the test's own (the build's bin/).
[[nodiscard]] std::string ProgramPath(const std::string& name);

/// Runs `argv` (its program a path, or a name looked up in PATH) to its end, stderr folded
/// into stdout. Gives up waiting for output after 5 minutes of silence.
[[nodiscard]] ProgramOutput RunProgram(const std::vector<std::string>& argv);

}  // namespace autodrive::eye::testing
