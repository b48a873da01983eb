#include "traffic/nema/internal/child_run.h"

#include <fmt/format.h>

#include <optional>

#include "traffic/nema/internal/io.h"

#include "common/error.h"
#include "common/process.h"

namespace autodrive::traffic::nema::internal {

ChildRun RunChild(const std::vector<std::string>& argv, const std::filesystem::path& dir,
                  std::chrono::milliseconds timeout,
                  const std::function<void(const std::filesystem::path&)>& read) {
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::filesystem::path output = dir / "output.txt";
  const std::filesystem::path report = dir / "report.json";
  ChildRun r;
  const auto started = std::chrono::steady_clock::now();
  try {
    ChildOptions options;
    options.output_file = output;
    ChildProcess child = ChildProcess::Start(argv, options);
    const std::optional<int> code = child.Wait(timeout);
    r.exit_code = code ? *code : child.Stop();
    if (!code) r.error = fmt::format("stopped after {} s", timeout.count() / 1000);
  } catch (const InputError& e) {
    r.error = e.what();
  }
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if ((r.exit_code == 0 || r.exit_code == 1) && std::filesystem::exists(report)) {
    try {
      read(report);
      r.ran = true;
    } catch (const std::exception& e) {  // nlohmann's parse and type errors
      r.error = fmt::format("{}: {}", report.string(), e.what());
    }
  } else if (r.error.empty()) {
    r.error = fmt::format("exit code {}: {}", r.exit_code, ReadFile(output));
  }
  return r;
}

}  // namespace autodrive::traffic::nema::internal
