#pragma once
/// @file
/// The DDS part of every program's command line, the same in every program of the project:
/// `--partition`, `--domain`, and DDS Security's `--keystore` and `--enclave`.
///
///   dds::ProgramOptions dds_cli("/autodrive/scm");   // the program's own identity
///   dds_cli.Add(app);
///   CLI11_PARSE(app, argc, argv);
///   dds::Participant participant(dds_cli.Participant());

#include <cstdlib>
#include <string>

#include <CLI/CLI.hpp>

#include "common/dds/participant.h"
#include "common/dds/security.h"

namespace autodrive::dds {

/// Adds `--keystore` and `--enclave` to `app` (or a subcommand), writing into `options`, which
/// should start from `SecurityOptions::FromEnvironment()` (as ROS 2 does).
/// `--keystore` enables security and enforces it: a keystore asked for on the command line
/// never degrades to an unsecured participant. `--enclave` only chooses the identity; it takes
/// effect when security is enabled (by `--keystore` or ROS_SECURITY_ENABLE=true).
inline void AddSecurityOptions(CLI::App& app, SecurityOptions& options) {
  app.add_option_function<std::string>(
         "--keystore",
         [&options](const std::string& keystore) {
           options.keystore = keystore;
           options.enabled = true;
           options.strategy = SecurityStrategy::kEnforce;
         },
         "DDS Security keystore (sros2 layout, made by autodrive-keystore); enables security, "
         "enforced. Default: ROS_SECURITY_KEYSTORE with ROS_SECURITY_ENABLE=true")
      ->group("DDS Security");
  app.add_option("--enclave", options.enclave,
                 "DDS Security enclave (identity), e.g. /autodrive/scm. Default: "
                 "ROS_SECURITY_ENCLAVE_OVERRIDE, else the program's own")
      ->group("DDS Security")
      ->capture_default_str();
}

/// The shipped DDS configuration a program uses when `CYCLONEDDS_URI` is not set:
/// `config/dds/localhost.xml` of the source tree the program was built in (found from the
/// executable's folder, `build/bin/../../config/dds`), or empty when there is none.
[[nodiscard]] std::string ShippedDdsConfig();

/// Sets `CYCLONEDDS_URI` to `file://` + `ShippedDdsConfig()` when it is unset or empty and that
/// file exists, and says so in the debug log (once); leaves a set variable alone. Call it before
/// the process's first participant (Cyclone reads the variable when it creates a domain).
void UseShippedDdsConfigUnlessSet();

/// A program's DDS options: where its participant lives (domain, partition) and who it is
/// (DDS Security). Keep it alive while `app` parses (the options write into it).
class ProgramOptions {
 public:
  /// `own_enclave`: the program's DDS Security identity, used unless `--enclave` or
  /// ROS_SECURITY_ENCLAVE_OVERRIDE names another. Empty when it depends on what the program
  /// reads: then call `SetOwnEnclave` before `Participant`.
  explicit ProgramOptions(std::string own_enclave = {})
      : security_(SecurityOptions::FromEnvironment()), own_enclave_(std::move(own_enclave)) {}

  /// Adds `--partition` (default: `AUTODRIVE_PARTITION` when set, as `autodrive-city up
  /// --partition` gives it to agents), `--domain`, `--keystore` and `--enclave` to `app`.
  void Add(CLI::App& app,
           const std::string& partition_help =
               "DDS partition (separates cities or test runs sharing a domain; default: the "
               "default partition, which ROS 2 uses)") {
    app.add_option("--partition", options_.partition, partition_help);
    app.add_option("--domain", options_.domain_id,
                   "DDS domain id (default: ROS_DOMAIN_ID, else Cyclone's default)");
    AddSecurityOptions(app, security_);
  }

  /// The identity used when neither `--enclave` nor the environment names one.
  void SetOwnEnclave(std::string enclave) { own_enclave_ = std::move(enclave); }

  /// The participant the options describe. When `CYCLONEDDS_URI` is not set, first sets it to
  /// the project's shipped configuration (`UseShippedDdsConfigUnlessSet`), so that a program
  /// started in a new shell finds the city `scripts/run-city` started.
  [[nodiscard]] ParticipantOptions Participant() const {
    UseShippedDdsConfigUnlessSet();
    ParticipantOptions o = options_;
    // A program the launcher starts as an agent gets its city's partition this way.
    if (const char* p = std::getenv("AUTODRIVE_PARTITION"); o.partition.empty() && p != nullptr) {
      o.partition = p;
    }
    SecurityOptions s = security_;
    if (s.enclave.empty()) s.enclave = own_enclave_;
    o.security = s;
    // The program's own identity names its ROS 2 node (not an enclave override, which many
    // processes may share), unless the launcher named the process.
    if (!own_enclave_.empty() || std::getenv("AUTODRIVE_PROCESS_NAME") != nullptr) {
      o.ros_node = RosNodeFor(own_enclave_);
    }
    return o;
  }

  [[nodiscard]] const std::string& partition() const { return options_.partition; }
  /// For programs that choose a partition themselves (a launcher's, a test's).
  void set_partition(std::string partition) { options_.partition = std::move(partition); }
  [[nodiscard]] const SecurityOptions& security() const { return security_; }

 private:
  ParticipantOptions options_;
  SecurityOptions security_;
  std::string own_enclave_;
};

}  // namespace autodrive::dds
