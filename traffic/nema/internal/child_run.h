#pragma once
/// @file
/// One run of the program as a child process (libsumo runs one simulation per process), as the
/// batches run them: its output to a file, its report read when it wrote one (not part of
/// traffic/nema's API).

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace autodrive::traffic::nema::internal {

/// How a child run ended.
struct ChildRun {
  int exit_code = -1;   ///< the child's (the program's: 0 and 1 are verdicts, 2 and 3 errors)
  bool ran = false;     ///< it wrote `report` and `read` took it
  std::string error;    ///< why it did not run (its output, or why it was stopped)
  double wall_s = 0.0;  ///< informative
};

/// Empties (or makes) the folder `dir`, runs `argv` (which writes its files there) with its
/// stdout and stderr in `dir`/output.txt, stopping it after `timeout`. When it exited 0 or 1
/// and wrote `dir`/report.json, calls `read` with that file (an exception it throws becomes the
/// error); otherwise the error has the exit code and the output.
[[nodiscard]] ChildRun RunChild(const std::vector<std::string>& argv,
                                const std::filesystem::path& dir, std::chrono::milliseconds timeout,
                                const std::function<void(const std::filesystem::path&)>& read);

}  // namespace autodrive::traffic::nema::internal
