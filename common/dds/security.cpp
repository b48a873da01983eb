#include "common/dds/security.h"

#include <dlfcn.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <system_error>
#include <utility>
#include <vector>

#include "common/error.h"

namespace autodrive::dds {
namespace fs = std::filesystem;

namespace {

constexpr std::array<const char*, 3> kPluginFiles = {
    "libdds_security_auth.so", "libdds_security_ac.so", "libdds_security_crypto.so"};

std::string Env(const char* name) {
  const char* value = std::getenv(name);
  return value == nullptr ? std::string() : std::string(value);
}

// "/" or "/a/b_c": tokens of [A-Za-z0-9_], none starting with a digit (ROS 2's name rules), so
// that the enclave names a folder inside the keystore and nothing else.
void ValidateEnclaveName(const std::string& enclave) {
  bool valid = !enclave.empty() && enclave.front() == '/';
  if (valid && enclave.size() > 1) {
    bool token_start = true;
    for (std::size_t i = 1; i < enclave.size() && valid; ++i) {
      const char c = enclave[i];
      if (c == '/') {
        valid = !token_start;
        token_start = true;
      } else {
        const bool digit = c >= '0' && c <= '9';
        valid = digit || c == '_' || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
        valid = valid && !(token_start && digit);
        token_start = false;
      }
    }
    valid = valid && !token_start;
  }
  AUTODRIVE_THROW_UNLESS(valid, "DDS Security enclave '"
                                    << enclave
                                    << "' is not an absolute ROS name such as /autodrive/scm "
                                       "(tokens of A-Z a-z 0-9 _, not starting with a digit)");
}

// Why `file` cannot be used, or "" when it is a readable regular file.
std::string FileProblem(const fs::path& file) {
  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (!fs::exists(status)) {
    return file.string() + " is missing";
  }
  if (!fs::is_regular_file(status)) {
    return file.string() + " is not a regular file";
  }
  if (::access(file.c_str(), R_OK) != 0) {
    return "cannot read " + file.string() + ": " + std::strerror(errno);
  }
  return "";
}

// The directory of the libddsc this process runs with (its real file, links resolved).
std::optional<fs::path> CycloneLibraryDirectory() {
  void* symbol = ::dlsym(RTLD_DEFAULT, "dds_create_participant");
  Dl_info info{};
  if (symbol == nullptr || ::dladdr(symbol, &info) == 0 || info.dli_fname == nullptr) {
    return std::nullopt;
  }
  std::error_code ec;
  const fs::path real = fs::canonical(info.dli_fname, ec);
  return (ec ? fs::path(info.dli_fname) : real).parent_path();
}

}  // namespace

SecurityOptions SecurityOptions::FromEnvironment() {
  SecurityOptions options;
  options.enabled = Env("ROS_SECURITY_ENABLE") == "true";
  options.strategy = Env("ROS_SECURITY_STRATEGY") == "Enforce" ? SecurityStrategy::kEnforce
                                                               : SecurityStrategy::kPermissive;
  options.keystore = Env("ROS_SECURITY_KEYSTORE");
  options.enclave = Env("ROS_SECURITY_ENCLAVE_OVERRIDE");
  if (options.enclave.empty()) {
    options.enclave = Env("ROS_SECURITY_ENCLAVE");
  }
  return options;
}

SecurityOptions SecurityOptions::Enforced(std::string keystore, std::string enclave) {
  SecurityOptions options;
  options.enabled = true;
  options.strategy = SecurityStrategy::kEnforce;
  options.keystore = std::move(keystore);
  options.enclave = std::move(enclave);
  return options;
}

std::optional<EnclaveFiles> ResolveEnclave(const SecurityOptions& options) {
  if (!options.enabled) {
    return std::nullopt;
  }
  const bool enforce = options.strategy == SecurityStrategy::kEnforce;
  const std::string enclave = options.enclave.empty() ? "/" : options.enclave;
  ValidateEnclaveName(enclave);

  if (options.keystore.empty()) {
    AUTODRIVE_THROW_UNLESS(!enforce,
                           "DDS Security is enabled and enforced (ROS_SECURITY_ENABLE=true, "
                           "ROS_SECURITY_STRATEGY=Enforce) but no keystore is given: set "
                           "ROS_SECURITY_KEYSTORE or --keystore (make one with "
                           "autodrive-keystore city KEYSTORE ...)");
    spdlog::warn(
        "DDS Security is enabled but no keystore is given (ROS_SECURITY_KEYSTORE): running "
        "UNSECURED (ROS_SECURITY_STRATEGY=Permissive)");
    return std::nullopt;
  }
  std::error_code ec;
  const fs::path keystore = fs::absolute(options.keystore, ec);
  AUTODRIVE_THROW_UNLESS(!ec,
                         "DDS Security keystore '" << options.keystore << "': " << ec.message());
  EnclaveFiles files;
  files.enclave = enclave;
  files.directory = (keystore / "enclaves" / enclave.substr(1)).lexically_normal();
  if (!fs::is_directory(files.directory, ec)) {
    const std::string why = fs::is_directory(keystore, ec)
                                ? "keystore " + keystore.string() + " has no enclave " + enclave +
                                      " (no folder " + files.directory.string() + ")"
                                : "keystore " + keystore.string() + " does not exist";
    AUTODRIVE_THROW_UNLESS(!enforce, "DDS Security (enforced): "
                                         << why << "; make it with autodrive-keystore enclave "
                                         << keystore.string() << " " << enclave << " --role ROLE");
    spdlog::warn("DDS Security: {}: running UNSECURED (ROS_SECURITY_STRATEGY=Permissive)", why);
    return std::nullopt;
  }
  files.identity_ca = files.directory / "identity_ca.cert.pem";
  files.certificate = files.directory / "cert.pem";
  files.private_key = files.directory / "key.pem";
  files.permissions_ca = files.directory / "permissions_ca.cert.pem";
  files.governance = files.directory / "governance.p7s";
  files.permissions = files.directory / "permissions.p7s";
  std::string problems;
  for (const fs::path* file : {&files.identity_ca, &files.certificate, &files.private_key,
                               &files.permissions_ca, &files.governance, &files.permissions}) {
    if (const std::string problem = FileProblem(*file); !problem.empty()) {
      problems += (problems.empty() ? "" : "; ") + problem;
    }
  }
  AUTODRIVE_THROW_UNLESS(problems.empty(), "DDS Security enclave " << enclave << ": " << problems
                                                                   << " (remake it with "
                                                                      "autodrive-keystore "
                                                                      "enclave)");
  return files;
}

fs::path SecurityPluginDirectory() {
  std::vector<fs::path> candidates;
  if (const std::string dir = Env("AUTODRIVE_DDS_SECURITY_PLUGINS"); !dir.empty()) {
    candidates.emplace_back(dir);  // an explicit choice does not fall back to others
  } else if (const auto lib = CycloneLibraryDirectory()) {
    candidates.push_back(*lib / "libddsc0debian");
    candidates.push_back(*lib);
  }
  for (const fs::path& dir : candidates) {
    bool all = true;
    for (const char* plugin : kPluginFiles) {
      all = all && FileProblem(dir / plugin).empty();
    }
    if (all) {
      return dir;
    }
  }
  std::string looked;
  for (const fs::path& dir : candidates) {
    looked += (looked.empty() ? "" : ", ") + dir.string();
  }
  throw InputError(
      "Cyclone DDS's security plugins (libdds_security_auth.so, libdds_security_ac.so, "
      "libdds_security_crypto.so) are not in " +
      (looked.empty() ? std::string("any known place (libddsc not found)") : looked) +
      ": install Debian's libddsc0debian, or set AUTODRIVE_DDS_SECURITY_PLUGINS to their "
      "directory");
}

namespace internal {

void SetSecurityProperties(dds_qos_t* qos, const EnclaveFiles& files,
                           const fs::path& plugin_directory) {
  const auto set = [qos](const char* name, const std::string& value) {
    dds_qset_prop(qos, name, value.c_str());
  };
  const auto uri = [](const fs::path& file) { return "file:" + file.string(); };
  // The plugins: full paths, since Debian keeps them off the library path.
  set("dds.sec.auth.library.path", (plugin_directory / "libdds_security_auth.so").string());
  set("dds.sec.auth.library.init", "init_authentication");
  set("dds.sec.auth.library.finalize", "finalize_authentication");
  set("dds.sec.access.library.path", (plugin_directory / "libdds_security_ac.so").string());
  set("dds.sec.access.library.init", "init_access_control");
  set("dds.sec.access.library.finalize", "finalize_access_control");
  set("dds.sec.crypto.library.path", (plugin_directory / "libdds_security_crypto.so").string());
  set("dds.sec.crypto.library.init", "init_crypto");
  set("dds.sec.crypto.library.finalize", "finalize_crypto");
  // The enclave, as rmw_cyclonedds passes an sros2 enclave.
  set("dds.sec.auth.identity_ca", uri(files.identity_ca));
  set("dds.sec.auth.identity_certificate", uri(files.certificate));
  set("dds.sec.auth.private_key", uri(files.private_key));
  set("dds.sec.access.permissions_ca", uri(files.permissions_ca));
  set("dds.sec.access.governance", uri(files.governance));
  set("dds.sec.access.permissions", uri(files.permissions));
}

}  // namespace internal
}  // namespace autodrive::dds
