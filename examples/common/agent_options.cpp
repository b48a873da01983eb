#include "examples/common/agent_options.h"

#include <utility>

namespace autodrive::examples {

AgentOptions::AgentOptions(std::string enclave, double rate_hz_default)
    : rate_hz(rate_hz_default), dds(std::move(enclave)) {}

void AgentOptions::Add(CLI::App& app) {
  app.add_option("--rate-hz", rate_hz, "decisions per second (not in lockstep)")
      ->check(CLI::Range(1.0, 200.0))
      ->capture_default_str();
  app.add_option("--lockstep", lockstep,
                 "take part in the simulator's lockstep as the controller of this name: decide "
                 "once per simulated step, on the simulated time (--rate-hz is then unused)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off")
      ->capture_default_str();
  dds.Add(app);
}

}  // namespace autodrive::examples
