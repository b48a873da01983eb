#pragma once
/// @file
/// DDS Security for a participant: which enclave of which keystore it authenticates with, taken
/// from the environment exactly as ROS 2 takes it, and the Cyclone DDS QoS properties that load
/// Cyclone's authentication, access-control and cryptography plugins with that enclave's files.
/// The keystore is laid out as ROS 2's sros2 lays it out (scripts/autodrive-keystore makes
/// one); see docs/security.md.

#include <dds/dds.h>

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace autodrive::dds {

/// What happens when security is enabled but there is no enclave to use (ROS 2's
/// `ROS_SECURITY_STRATEGY`).
enum class SecurityStrategy {
  /// No keystore, or no folder for the enclave: the participant runs unsecured and a warning
  /// is logged (ROS 2's default).
  kPermissive,
  /// No keystore, or no folder for the enclave: creating the participant throws.
  kEnforce,
};

/// The DDS Security part of `ParticipantOptions`: whether a participant is secured and with
/// which identity. The default is unsecured (a closed bench).
struct SecurityOptions {
  /// Secure the participant (ROS 2's `ROS_SECURITY_ENABLE=true`).
  bool enabled = false;
  /// See `SecurityStrategy` (`ROS_SECURITY_STRATEGY=Enforce|Permissive`).
  SecurityStrategy strategy = SecurityStrategy::kPermissive;
  /// The keystore directory (`ROS_SECURITY_KEYSTORE`), holding `enclaves/<enclave>/`.
  std::string keystore;
  /// The enclave, an absolute ROS name such as "/autodrive/scm" (`ROS_SECURITY_ENCLAVE_OVERRIDE`
  /// or `ROS_SECURITY_ENCLAVE`). Empty is ROS 2's default enclave "/".
  std::string enclave;

  /// The settings ROS 2 reads from the environment: `ROS_SECURITY_ENABLE` ("true" enables;
  /// anything else or unset does not), `ROS_SECURITY_STRATEGY` ("Enforce" enforces; anything
  /// else is permissive), `ROS_SECURITY_KEYSTORE`, and the enclave from
  /// `ROS_SECURITY_ENCLAVE_OVERRIDE` (ROS 2's name) or else `ROS_SECURITY_ENCLAVE`. Never
  /// throws: the values are checked when a participant uses them.
  [[nodiscard]] static SecurityOptions FromEnvironment();

  /// Enables security with `keystore` and `enclave`, enforced: what a program does when it is
  /// told explicitly where its identity is (an explicit request never degrades to unsecured).
  [[nodiscard]] static SecurityOptions Enforced(std::string keystore, std::string enclave);
};

/// The files of one enclave, all regular and readable, with absolute paths.
struct EnclaveFiles {
  std::string enclave;  ///< the enclave's name, e.g. "/autodrive/scm"
  std::filesystem::path directory;
  std::filesystem::path identity_ca;     ///< identity_ca.cert.pem
  std::filesystem::path certificate;     ///< cert.pem (subject CN=<enclave>)
  std::filesystem::path private_key;     ///< key.pem
  std::filesystem::path permissions_ca;  ///< permissions_ca.cert.pem
  std::filesystem::path governance;      ///< governance.p7s
  std::filesystem::path permissions;     ///< permissions.p7s
};

/// Decides whether a participant with `options` is secured and finds its enclave's files.
/// Returns nullopt when it runs unsecured: security disabled, or (permissive only, with a
/// logged warning) no keystore or no folder for the enclave. Throws `InputError` for an
/// invalid enclave name; with `kEnforce`, for no keystore or no enclave folder; and in either
/// strategy for an enclave folder whose files are incomplete (naming the missing or unreadable
/// file), since a half-made enclave is a mistake rather than an absence.
[[nodiscard]] std::optional<EnclaveFiles> ResolveEnclave(const SecurityOptions& options);

/// The directory holding Cyclone DDS's security plugins (`libdds_security_auth.so`, `_ac`,
/// `_crypto`): `AUTODRIVE_DDS_SECURITY_PLUGINS` when set, else beside the `libddsc` this
/// process runs with, in its `libddsc0debian/` subdirectory (Debian's layout) or the same
/// directory (upstream's). Throws `InputError` listing where it looked when none has them.
[[nodiscard]] std::filesystem::path SecurityPluginDirectory();

namespace internal {
/// Adds the `dds.sec.*` properties that secure a participant with `files` to `qos`: the three
/// plugins (from `plugin_directory`) and the enclave's CA certificates, identity, governance
/// and permissions, as `file:` URIs.
void SetSecurityProperties(dds_qos_t* qos, const EnclaveFiles& files,
                           const std::filesystem::path& plugin_directory);
}  // namespace internal

}  // namespace autodrive::dds
