#pragma once
/// @file
/// Command-line options for DDS Security, for programs that parse their flags with CLI11 (the
/// program links CLI11; the common library does not need it).
///
///   auto security = dds::SecurityOptions::FromEnvironment();   // as ROS 2
///   if (security.enclave.empty()) security.enclave = "/autodrive/scm";  // the program's own
///   dds::AddSecurityOptions(app, security);                     // --keystore, --enclave
///   CLI11_PARSE(app, argc, argv);
///   dds::ParticipantOptions options;
///   options.security = security;

#include <string>

#include <CLI/CLI.hpp>

#include "common/dds/security.h"

namespace autodrive::dds {

/// Adds `--keystore DIR` and `--enclave NAME` (group "DDS Security") to `app`, bound to
/// `options`, which the caller fills first (from the environment, then its default enclave).
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

}  // namespace autodrive::dds
