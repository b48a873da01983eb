#include "common/dds/program_options.h"

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "common/process.h"

namespace autodrive::dds {

std::string ShippedDdsConfig() {
  const std::filesystem::path file =
      std::filesystem::path(ExecutableDir()) / ".." / ".." / "config" / "dds" / "localhost.xml";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return {};
  return std::filesystem::weakly_canonical(file, ec).string();
}

void UseShippedDdsConfigUnlessSet() {
  static std::once_flag once;
  std::call_once(once, [] {
    const char* set = std::getenv("CYCLONEDDS_URI");
    if (set != nullptr && *set != '\0') return;
    const std::string file = ShippedDdsConfig();
    if (file.empty()) {
      // Cyclone's defaults send a heartbeat every 100 ms, which the simulator's lockstep waits
      // for twice a step: a run goes some fifty times slower than with the shipped file.
      spdlog::warn(
          "CYCLONEDDS_URI is not set and there is no config/dds/localhost.xml beside this "
          "program ({}): Cyclone DDS's defaults, under which a lockstep run is very slow; set "
          "CYCLONEDDS_URI=file:///PATH/TO/config/dds/localhost.xml",
          ExecutableDir());
      return;
    }
    ::setenv("CYCLONEDDS_URI", ("file://" + file).c_str(), 1);
    spdlog::info(
        "CYCLONEDDS_URI is not set: using {} (loopback only, as scripts/run-city does; set "
        "CYCLONEDDS_URI to config/dds/lab.xml for a lab of several hosts)",
        file);
  });
}

}  // namespace autodrive::dds
