#pragma once
/// @file
/// The options every example agent takes besides its own: how it is clocked (`--lockstep NAME`
/// in the twin, as the scenario runner starts agents; else `--rate-hz` decisions a second on the
/// wall clock, on a real car), its log level, and DDS's (partition, domain, security).
///
/// An agent parses them, then makes its `ShutdownSignals` at once, before anything can start a
/// thread (a map's build may start TBB's, libtorch its own): a thread that does not block
/// SIGTERM may take it with its default action, and the program dies without its last words
/// (common/shutdown.h).

#include <string>

#include <CLI/CLI.hpp>

#include "common/dds/program_options.h"

namespace autodrive::examples {

struct AgentOptions {
  /// `enclave`: the agent's DDS Security identity (dds::ProgramOptions); `rate_hz`: its
  /// decisions a second off the lockstep, unless `--rate-hz` says otherwise.
  AgentOptions(std::string enclave, double rate_hz);

  /// Adds `--rate-hz`, `--lockstep`, `--log-level` and DDS's options to `app`.
  void Add(CLI::App& app);

  double rate_hz;
  std::string lockstep;  ///< empty: the wall clock
  std::string log_level = "info";
  dds::ProgramOptions dds;
};

}  // namespace autodrive::examples
