#include "common/config.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <system_error>

namespace autodrive::config::internal {
namespace {

constexpr std::size_t kMaxShownChars = 60;
constexpr std::int64_t kNanosPerSecond = 1'000'000'000;

// "LINE:COLUMN", 1-based. A null mark (an empty document) is reported at 1:1.
std::string FormatMark(const YAML::Mark& mark) {
  if (mark.is_null() || mark.line < 0 || mark.column < 0) return "1:1";
  return std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

std::string ErrnoText(int error) {
  return std::error_code(error, std::generic_category()).message();
}

// Escapes control characters, quotes and backslashes; cuts long text (on a UTF-8 boundary).
std::string Escape(std::string_view text) {
  bool cut = false;
  if (text.size() > kMaxShownChars) {
    std::size_t end = kMaxShownChars;
    while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0U) == 0x80U) --end;
    text = text.substr(0, end);
    cut = true;
  }
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (byte < 0x20U || byte == 0x7FU) {
          constexpr char kHex[] = "0123456789abcdef";
          out += "\\x";
          out += kHex[byte >> 4U];
          out += kHex[byte & 0xFU];
        } else {
          out += c;
        }
    }
  }
  if (cut) out += "...";
  return out;
}

bool IsDigit(char c) { return c >= '0' && c <= '9'; }

// A number, bool or null must be a plain scalar: `"3"` is the string 3.
bool IsPlainScalar(const YAML::Node& node) { return node.IsScalar() && node.Tag() == "?"; }

[[noreturn]] void FailWrongType(const YAML::Node& node, const Loc& loc, std::string_view expected) {
  Fail(loc, "wrong type (got " + Describe(node) + "; expected " + std::string(expected) + ")");
}

[[noreturn]] void FailOutOfRange(const YAML::Node& node, const Loc& loc,
                                 std::string_view expected) {
  Fail(loc, "out of range (got " + Describe(node) + "; expected " + std::string(expected) + ")");
}

// [-+]?[0-9]+
bool IsDecimalInteger(std::string_view text) {
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) text.remove_prefix(1);
  return !text.empty() && std::all_of(text.begin(), text.end(), IsDigit);
}

// [-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?  (YAML 1.2 core schema float, finite)
bool IsDecimalNumber(std::string_view text) {
  std::size_t i = 0;
  const auto digits = [&] {
    const std::size_t start = i;
    while (i < text.size() && IsDigit(text[i])) ++i;
    return i - start;
  };
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
  const std::size_t integer_digits = digits();
  std::size_t fraction_digits = 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    fraction_digits = digits();
  }
  if (integer_digits == 0 && fraction_digits == 0) return false;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  return i == text.size();
}

// The YAML 1.2 core schema's non-finite floats; nullopt if `text` is none of them.
std::optional<double> NonFinite(std::string_view text) {
  double sign = 1.0;
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    sign = text.front() == '-' ? -1.0 : 1.0;
    if (text.substr(1) == ".nan" || text.substr(1) == ".NaN" || text.substr(1) == ".NAN") {
      return std::nullopt;  // a signed NaN is not YAML
    }
    text.remove_prefix(1);
  }
  if (text == ".inf" || text == ".Inf" || text == ".INF") {
    return sign * std::numeric_limits<double>::infinity();
  }
  if (text == ".nan" || text == ".NaN" || text == ".NAN") {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return std::nullopt;
}

template <typename F>
F ParseFloating(const YAML::Node& node, const Loc& loc, bool allow_non_finite,
                std::string_view type_name) {
  const std::string_view expected = allow_non_finite ? "a number" : "a finite number";
  if (!IsPlainScalar(node)) FailWrongType(node, loc, expected);
  std::string_view text = node.Scalar();
  if (const std::optional<double> special = NonFinite(text)) {
    if (!allow_non_finite) FailOutOfRange(node, loc, expected);
    return static_cast<F>(*special);
  }
  if (!IsDecimalNumber(text)) FailWrongType(node, loc, expected);
  if (text.front() == '+') text.remove_prefix(1);
  F value{};
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::result_out_of_range) {
    FailOutOfRange(node, loc, "a number that fits a " + std::string(type_name));
  }
  AUTODRIVE_CHECK(error == std::errc() && end == text.data() + text.size(), "from_chars: " << text);
  return value;
}

template <typename F>
std::string FormatFloating(F value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  AUTODRIVE_CHECK(result.ec == std::errc());
  std::string text(buffer, result.ptr);
  // Integral values get ".0" so that other YAML readers see a float.
  if (text.find_first_not_of("-0123456789") == std::string::npos) text += ".0";
  return text;
}

enum class ParseStatus { kOk, kWrongType, kOutOfRange };

// Exact conversion of decimal seconds to nanoseconds, rounded half away from zero.
ParseStatus SecondsToNanos(std::string_view text, std::int64_t& ns) {
  if (!IsDecimalNumber(text)) return ParseStatus::kWrongType;
  std::size_t i = 0;
  bool negative = false;
  if (text[i] == '+' || text[i] == '-') negative = text[i++] == '-';
  std::string digits;
  std::int64_t fraction_digits = 0;
  bool in_fraction = false;
  for (; i < text.size() && text[i] != 'e' && text[i] != 'E'; ++i) {
    if (text[i] == '.') {
      in_fraction = true;
      continue;
    }
    digits += text[i];
    if (in_fraction) ++fraction_digits;
  }
  std::int64_t exponent = 0;
  if (i < text.size()) {
    ++i;  // 'e'
    bool exponent_negative = false;
    if (text[i] == '+' || text[i] == '-') exponent_negative = text[i++] == '-';
    for (; i < text.size(); ++i) {
      exponent = std::min<std::int64_t>(exponent * 10 + (text[i] - '0'), 1'000'000);
    }
    if (exponent_negative) exponent = -exponent;
  }
  const std::size_t first = digits.find_first_not_of('0');
  if (first == std::string::npos) {
    ns = 0;
    return ParseStatus::kOk;
  }
  digits.erase(0, first);
  // The value in nanoseconds is digits * 10^shift.
  std::int64_t shift = exponent - fraction_digits + 9;
  while (digits.back() == '0') {
    digits.pop_back();
    ++shift;
  }
  constexpr std::uint64_t kMax = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t magnitude = 0;
  const auto append = [&](char digit) {
    const auto d = static_cast<std::uint64_t>(digit - '0');
    if (magnitude > (kMax - d) / 10) return false;
    magnitude = magnitude * 10 + d;
    return true;
  };
  const auto length = static_cast<std::int64_t>(digits.size());
  if (shift >= 0) {
    if (length + shift > 20) return ParseStatus::kOutOfRange;
    for (const char digit : digits) {
      if (!append(digit)) return ParseStatus::kOutOfRange;
    }
    for (std::int64_t k = 0; k < shift; ++k) {
      if (!append('0')) return ParseStatus::kOutOfRange;
    }
  } else {
    const std::int64_t kept = length + shift;  // digits left of the nanosecond point
    if (kept > 20) return ParseStatus::kOutOfRange;
    for (std::int64_t k = 0; k < kept; ++k) {
      if (!append(digits[static_cast<std::size_t>(k)])) return ParseStatus::kOutOfRange;
    }
    if (kept >= 0 && digits[static_cast<std::size_t>(kept)] >= '5') {
      if (magnitude == kMax) return ParseStatus::kOutOfRange;
      ++magnitude;
    }
  }
  constexpr auto kMaxPositive =
      static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  if (!negative) {
    if (magnitude > kMaxPositive) return ParseStatus::kOutOfRange;
    ns = static_cast<std::int64_t>(magnitude);
  } else {
    if (magnitude > kMaxPositive + 1) return ParseStatus::kOutOfRange;
    ns = magnitude == kMaxPositive + 1 ? std::numeric_limits<std::int64_t>::min()
                                       : -static_cast<std::int64_t>(magnitude);
  }
  return ParseStatus::kOk;
}

// Valid UTF-8 (no overlong forms, no surrogates) without noncharacters, which yaml-cpp 0.7
// does not round-trip.
bool IsSavableUtf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto lead = static_cast<unsigned char>(text[i]);
    std::size_t length = 0;
    std::uint32_t code_point = 0;
    if (lead < 0x80U) {
      ++i;
      continue;
    } else if ((lead & 0xE0U) == 0xC0U) {
      length = 2;
      code_point = lead & 0x1FU;
    } else if ((lead & 0xF0U) == 0xE0U) {
      length = 3;
      code_point = lead & 0x0FU;
    } else if ((lead & 0xF8U) == 0xF0U) {
      length = 4;
      code_point = lead & 0x07U;
    } else {
      return false;
    }
    if (i + length > text.size()) return false;
    for (std::size_t k = 1; k < length; ++k) {
      const auto byte = static_cast<unsigned char>(text[i + k]);
      if ((byte & 0xC0U) != 0x80U) return false;
      code_point = (code_point << 6U) | (byte & 0x3FU);
    }
    constexpr std::uint32_t kMinForLength[] = {0, 0, 0x80, 0x800, 0x10000};
    if (code_point < kMinForLength[length] || code_point > 0x10FFFFU) return false;
    if (code_point >= 0xD800U && code_point <= 0xDFFFU) return false;
    if (code_point >= 0xFDD0U && code_point <= 0xFDEFU) return false;
    if ((code_point & 0xFFFEU) == 0xFFFEU) return false;
    i += length;
  }
  return true;
}

// Text that yaml-cpp writes and reads back unchanged as a plain scalar, also inside a flow
// sequence: words, dots, slashes, dashes and inner spaces.
bool IsSafePlain(std::string_view text) {
  if (text.empty() || text == "null" || text == "Null" || text == "NULL") return false;
  if (text.back() == ' ') return false;
  const auto word = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || IsDigit(c) || c == '_';
  };
  if (!word(text.front()) && text.front() != '/') return false;
  return std::all_of(text.begin(), text.end(), [&](char c) {
    return word(c) || c == '.' || c == '/' || c == '-' || c == ' ';
  });
}

// Optimal string alignment distance (edits, with adjacent transpositions), for "did you mean".
std::size_t EditDistance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}

std::string UnknownKeyMessage(std::string_view key, const std::vector<std::string>& allowed) {
  std::string message = "unknown key (";
  std::size_t best = 3;
  const std::string* suggestion = nullptr;
  for (const std::string& candidate : allowed) {
    const std::size_t distance = EditDistance(key, candidate);
    if (distance < best && distance < std::min(key.size(), candidate.size())) {
      best = distance;
      suggestion = &candidate;
    }
  }
  if (suggestion != nullptr) message += "did you mean " + *suggestion + "? ";
  message += "allowed keys: ";
  if (allowed.empty()) message += "none";
  for (std::size_t i = 0; i < allowed.size(); ++i) {
    if (i > 0) message += ", ";
    message += allowed[i];
  }
  return message + ")";
}

YAML::Mark ValueMark(const YAML::Node& key, const YAML::Node& value) {
  // An empty value (`key:`) is a null whose mark points at the next token: use the key's.
  return value.IsNull() ? key.Mark() : value.Mark();
}

std::string QuotedList(const std::vector<std::string_view>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out += ", ";
    out += Quote(names[i]);
  }
  return out;
}

}  // namespace

void Fail(const Loc& loc, std::string_view message) {
  throw ConfigError(*loc.file + ":" + FormatMark(loc.mark) + ": " +
                    (loc.path.empty() ? std::string("<root>") : loc.path) + ": " +
                    std::string(message));
}

std::string JoinKey(std::string_view path, std::string_view key) {
  const bool identifier = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || IsDigit(c) || c == '_' || c == '-';
  });
  if (!identifier) return std::string(path) + "[" + Quote(key) + "]";
  if (path.empty()) return std::string(key);
  return std::string(path) + "." + std::string(key);
}

std::string JoinIndex(std::string_view path, std::size_t index) {
  return std::string(path) + "[" + std::to_string(index) + "]";
}

namespace {
void SetBlockStyle(YAML::Node node) {
  if (node.IsMap() || node.IsSequence()) {
    node.SetStyle(YAML::EmitterStyle::Block);
    for (auto it = node.begin(); it != node.end(); ++it) {
      SetBlockStyle(node.IsMap() ? it->second : *it);
    }
  }
}
}  // namespace

std::string DumpSection(const YAML::Node& node) {
  YAML::Node copy = YAML::Clone(node);
  SetBlockStyle(copy);
  return YAML::Dump(copy);
}

std::string Quote(std::string_view text) { return "\"" + Escape(text) + "\""; }

std::string Describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Undefined:
      return "nothing";
    case YAML::NodeType::Null:
      return "null";
    case YAML::NodeType::Sequence:
      return "a sequence";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Scalar:
      break;
  }
  if (node.Tag() == "?") return Escape(node.Scalar());
  if (node.Tag() == "!") return "the string " + Quote(node.Scalar());
  return Quote(node.Scalar()) + " tagged " + node.Tag();
}

void CheckMappingKeys(const YAML::Node& node, const Loc& loc,
                      const std::vector<std::string>* allowed) {
  if (!node.IsMap()) FailWrongType(node, loc, "a mapping");
  std::vector<std::pair<std::string, YAML::Mark>> seen;
  for (auto it = node.begin(); it != node.end(); ++it) {
    const YAML::Node key = it->first;
    if (!key.IsScalar()) {
      FailWrongType(key, Loc{loc.file, key.Mark(), loc.path}, "a string key");
    }
    const std::string& name = key.Scalar();
    const Loc key_loc{loc.file, key.Mark(), JoinKey(loc.path, name)};
    const auto previous = std::find_if(seen.begin(), seen.end(),
                                       [&](const auto& entry) { return entry.first == name; });
    if (previous != seen.end()) {
      const YAML::Mark& first = previous->second;
      Fail(key_loc, "duplicate key (first defined at line " + std::to_string(first.line + 1) +
                        ", column " + std::to_string(first.column + 1) + ")");
    }
    if (allowed != nullptr && std::find(allowed->begin(), allowed->end(), name) == allowed->end()) {
      Fail(key_loc, UnknownKeyMessage(name, *allowed));
    }
    seen.emplace_back(name, key.Mark());
  }
}

std::optional<Entry> FindKey(const YAML::Node& map, std::string_view key) {
  for (auto it = map.begin(); it != map.end(); ++it) {
    if (it->first.IsScalar() && it->first.Scalar() == key) {
      return Entry{it->second, ValueMark(it->first, it->second)};
    }
  }
  return std::nullopt;
}

std::vector<std::pair<std::string, Entry>> Entries(const YAML::Node& map) {
  std::vector<std::pair<std::string, Entry>> entries;
  for (auto it = map.begin(); it != map.end(); ++it) {
    entries.emplace_back(it->first.Scalar(), Entry{it->second, ValueMark(it->first, it->second)});
  }
  return entries;
}

void ExpectSequence(const YAML::Node& node, const Loc& loc) {
  if (!node.IsSequence()) FailWrongType(node, loc, "a sequence");
}

bool ParseBool(const YAML::Node& node, const Loc& loc) {
  if (IsPlainScalar(node)) {
    if (node.Scalar() == "true") return true;
    if (node.Scalar() == "false") return false;
  }
  FailWrongType(node, loc, "true or false");
}

std::int64_t ParseSigned(const YAML::Node& node, const Loc& loc, std::int64_t min,
                         std::int64_t max) {
  const std::string expected =
      "an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
  if (!IsPlainScalar(node) || !IsDecimalInteger(node.Scalar())) {
    FailWrongType(node, loc, expected);
  }
  std::string_view text = node.Scalar();
  if (text.front() == '+') text.remove_prefix(1);
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::result_out_of_range || value < min || value > max) {
    FailOutOfRange(node, loc, expected);
  }
  AUTODRIVE_CHECK(error == std::errc() && end == text.data() + text.size());
  return value;
}

std::uint64_t ParseUnsigned(const YAML::Node& node, const Loc& loc, std::uint64_t max) {
  const std::string expected = "an integer in [0, " + std::to_string(max) + "]";
  if (!IsPlainScalar(node) || !IsDecimalInteger(node.Scalar())) {
    FailWrongType(node, loc, expected);
  }
  std::string_view text = node.Scalar();
  if (text.front() == '-') {
    // Only zero may carry a minus sign.
    if (text.find_first_not_of('0', 1) != std::string_view::npos) {
      FailOutOfRange(node, loc, expected);
    }
    return 0;
  }
  if (text.front() == '+') text.remove_prefix(1);
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::result_out_of_range || value > max) FailOutOfRange(node, loc, expected);
  AUTODRIVE_CHECK(error == std::errc() && end == text.data() + text.size());
  return value;
}

double ParseDouble(const YAML::Node& node, const Loc& loc, bool allow_non_finite) {
  return ParseFloating<double>(node, loc, allow_non_finite, "double");
}

float ParseFloat(const YAML::Node& node, const Loc& loc, bool allow_non_finite) {
  return ParseFloating<float>(node, loc, allow_non_finite, "float");
}

std::string ParseString(const YAML::Node& node, const Loc& loc) {
  if (!node.IsScalar()) FailWrongType(node, loc, "a string");
  return node.Scalar();
}

std::chrono::nanoseconds ParseDuration(const YAML::Node& node, const Loc& loc) {
  constexpr std::string_view kExpected = "a number of seconds";
  if (!IsPlainScalar(node)) FailWrongType(node, loc, kExpected);
  std::int64_t ns = 0;
  switch (SecondsToNanos(node.Scalar(), ns)) {
    case ParseStatus::kOk:
      return std::chrono::nanoseconds(ns);
    case ParseStatus::kWrongType:
      FailWrongType(node, loc, kExpected);
    case ParseStatus::kOutOfRange:
      FailOutOfRange(node, loc,
                     "a number of seconds in [" +
                         FormatSeconds(std::numeric_limits<std::int64_t>::min()) + ", " +
                         FormatSeconds(std::numeric_limits<std::int64_t>::max()) + "]");
  }
  AUTODRIVE_CHECK(false, "unreachable");
}

std::size_t ParseName(const YAML::Node& node, const Loc& loc,
                      const std::vector<std::string_view>& names) {
  if (!node.IsScalar()) FailWrongType(node, loc, "one of " + QuotedList(names));
  const auto found = std::find(names.begin(), names.end(), node.Scalar());
  if (found == names.end()) {
    Fail(loc, "not an allowed value (got " + Quote(node.Scalar()) + "; expected one of " +
                  QuotedList(names) + ")");
  }
  return static_cast<std::size_t>(found - names.begin());
}

void CheckOneOf(const Loc& loc, const std::string& value, const OneOf& one_of) {
  if (std::find(one_of.allowed.begin(), one_of.allowed.end(), value) != one_of.allowed.end()) {
    return;
  }
  const std::vector<std::string_view> names(one_of.allowed.begin(), one_of.allowed.end());
  Fail(loc, "not an allowed value (got " + Quote(value) + "; expected one of " + QuotedList(names) +
                ")");
}

std::string FormatDouble(double value) { return FormatFloating(value); }

std::string FormatFloat(float value) { return FormatFloating(value); }

std::string FormatSeconds(std::int64_t ns) {
  // The magnitude as unsigned, so that the most negative value does not overflow.
  const std::uint64_t magnitude =
      ns < 0 ? static_cast<std::uint64_t>(-(ns + 1)) + 1 : static_cast<std::uint64_t>(ns);
  constexpr auto kPerSecond = static_cast<std::uint64_t>(kNanosPerSecond);
  std::string text = (ns < 0 ? "-" : "") + std::to_string(magnitude / kPerSecond);
  std::string fraction = std::to_string(magnitude % kPerSecond);
  fraction.insert(0, 9 - fraction.size(), '0');
  while (fraction.size() > 1 && fraction.back() == '0') fraction.pop_back();
  return text + "." + fraction;
}

void WriteString(YAML::Emitter& out, std::string_view path, std::string_view text) {
  if (!IsSavableUtf8(text)) {
    throw ConfigError((path.empty() ? std::string("<root>") : std::string(path)) +
                      ": cannot save (got a string that is not valid UTF-8 or holds a Unicode "
                      "noncharacter; expected valid UTF-8)");
  }
  if (IsSafePlain(text)) {
    out << std::string(text);
  } else {
    out << YAML::DoubleQuoted << std::string(text);
  }
}

void WritePlain(YAML::Emitter& out, const std::string& text) { out << text; }

void ConfigureEmitter(YAML::Emitter& out) {
  out.SetIndent(2);
  out.SetMapFormat(YAML::Block);
  out.SetSeqFormat(YAML::Block);
  out.SetNullFormat(YAML::LowerNull);
}

std::string FinishEmitter(const YAML::Emitter& out) {
  AUTODRIVE_CHECK(out.good(), "yaml-cpp emitter error: " << out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

Document ParseDocument(const std::string& yaml, std::string name, std::string_view key) {
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(yaml);
  } catch (const YAML::Exception& e) {
    throw ConfigError(name + ":" + FormatMark(e.mark) + ": YAML syntax error (" + e.msg + ")");
  }
  Document document{std::move(name), YAML::Node(), YAML::Mark::null_mark(), ""};
  const Loc root_loc{&document.file, YAML::Mark::null_mark(), ""};
  if (documents.empty()) Fail(root_loc, "wrong type (got an empty document; expected a mapping)");
  if (documents.size() > 1) {
    Fail(Loc{&document.file, documents[1].Mark(), ""},
         "more than one YAML document (expected exactly one)");
  }
  document.root = documents.front();
  document.mark = document.root.Mark();
  if (key.empty()) return document;
  const Loc loc{&document.file, document.mark, ""};
  CheckMappingKeys(document.root, loc, /*allowed=*/nullptr);
  const std::optional<Entry> entry = FindKey(document.root, key);
  if (!entry) Fail(Loc{&document.file, document.mark, JoinKey("", key)}, "missing required key");
  document.root = entry->value;
  document.mark = entry->mark;
  document.path = JoinKey("", key);
  return document;
}

}  // namespace autodrive::config::internal

namespace autodrive::config {

using internal::ErrnoText;

std::string ReadFile(const std::filesystem::path& path) {
  const auto fail = [&](int error) {
    throw ConfigError(path.string() + ": cannot read file (" + ErrnoText(error) + ")");
  };
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"),
                                                             &std::fclose);
  if (!file) fail(errno);
  std::string text;
  char buffer[65536];
  while (true) {
    const std::size_t n = std::fread(buffer, 1, sizeof(buffer), file.get());
    text.append(buffer, n);
    if (n < sizeof(buffer)) break;
  }
  if (std::ferror(file.get()) != 0) fail(errno);
  return text;
}

void WriteFile(const std::filesystem::path& path, std::string_view text) {
  const auto fail = [&](int error) {
    throw ConfigError(path.string() + ": cannot write file (" + ErrnoText(error) + ")");
  };
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) fail(errno);
  const std::size_t written = std::fwrite(text.data(), 1, text.size(), file);
  const int write_error = errno;
  if (std::fclose(file) != 0) fail(errno);
  if (written != text.size()) fail(write_error);
}

}  // namespace autodrive::config
