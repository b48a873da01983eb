#include "common/ids.h"

#include <charconv>
#include <cstdint>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>

#include "common/error.h"

namespace autodrive {
namespace {

// Longest piece of rejected text quoted in an error message; names come from the network.
constexpr std::size_t kMaxQuotedBytes = 64;

// `text` in double quotes with non-printable bytes, quotes and backslashes escaped, and
// truncated to kMaxQuotedBytes bytes (saying so and giving the full length).
std::string Quote(std::string_view text) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "\"";
  for (const char c : text.substr(0, kMaxQuotedBytes)) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte >= 0x7f) {
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    } else {
      out += c;
    }
  }
  out += '"';
  if (text.size() > kMaxQuotedBytes) {
    out += " (truncated, " + std::to_string(text.size()) + " bytes)";
  }
  return out;
}

[[noreturn]] void ThrowBadName(std::string_view name, std::string_view prefix,
                               std::string_view function) {
  std::ostringstream message;
  message << function << ": expected \"" << prefix << "<n>\" with n a decimal number from 0 to "
          << std::numeric_limits<std::uint32_t>::max() << " without sign or leading zeros, got "
          << Quote(name);
  throw InputError(message.str());
}

// The number n of a name `<prefix><n>`, n in decimal without sign or leading zeros, fitting in
// uint32; InputError naming `function`, the expected form and the text seen otherwise.
std::uint32_t ParseIndexedName(std::string_view name, std::string_view prefix,
                               std::string_view function) {
  const auto fail = [&] { ThrowBadName(name, prefix, function); };
  if (!name.starts_with(prefix)) {
    fail();
  }
  const std::string_view digits = name.substr(prefix.size());
  if (digits.empty() || (digits.size() > 1 && digits.front() == '0')) {
    fail();
  }
  for (const char c : digits) {
    if (c < '0' || c > '9') {
      fail();
    }
  }
  std::uint32_t value = 0;
  const char* end = digits.data() + digits.size();
  const auto [ptr, ec] = std::from_chars(digits.data(), end, value);
  if (ec != std::errc() || ptr != end) {
    fail();
  }
  return value;
}

}  // namespace

std::string VehicleName(VehicleId id) {
  return std::string(kVehicleNamePrefix) + std::to_string(id.value());
}

VehicleId ParseVehicleName(std::string_view name) {
  return VehicleId(ParseIndexedName(name, kVehicleNamePrefix, "ParseVehicleName"));
}

std::string SignalHeadName(SignalHeadId id) {
  return std::string(kSignalHeadNamePrefix) + std::to_string(id.value());
}

SignalHeadId ParseSignalHeadName(std::string_view name) {
  return SignalHeadId(ParseIndexedName(name, kSignalHeadNamePrefix, "ParseSignalHeadName"));
}

std::string RandomToken() {
  std::random_device random;
  static_assert(sizeof(std::random_device::result_type) >= 4);
  std::string out;
  for (int i = 0; i < 4; ++i) out += fmt::format("{:08x}", random() & 0xffffffffu);
  return out;
}

}  // namespace autodrive
