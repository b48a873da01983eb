#include "infrastructure/serial_protocol.h"

#include <charconv>
#include <vector>

#include "infrastructure/internal/overloaded.h"

namespace autodrive::infrastructure::serial {
namespace {

// Words separated by single spaces; empty words (double spaces) are kept so they fail parsing.
std::vector<std::string_view> Words(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t start = 0;
  for (;;) {
    const std::size_t space = line.find(' ', start);
    words.push_back(line.substr(start, space == std::string_view::npos ? space : space - start));
    if (space == std::string_view::npos) break;
    start = space + 1;
  }
  return words;
}

// A printable, bounded copy of received text for messages.
std::string Printable(std::string_view text) {
  std::string out;
  for (const char c : text.substr(0, kMaxLineLength)) {
    if (c >= 0x20 && c < 0x7f) {
      out += c;
    } else {
      static constexpr char kHex[] = "0123456789abcdef";
      const auto byte = static_cast<unsigned char>(c);
      out += "\\x";
      out += kHex[byte >> 4];
      out += kHex[byte & 0xf];
    }
  }
  return out;
}

void ExpectWords(const std::vector<std::string_view>& words, std::size_t n, std::string_view line) {
  if (words.size() != n) {
    throw ProtocolError("malformed",
                        "'" + Printable(line) + "' (expected " + std::to_string(n) + " words)");
  }
}

// A word that is a decimal integer.
std::optional<int> ParseInt(std::string_view word) {
  int value = 0;
  const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
  if (ec != std::errc() || end != word.data() + word.size() || word.empty()) return std::nullopt;
  return value;
}

Lamp ParseLamp(std::string_view word) {
  const auto lamp = LampFromString(word);
  if (!lamp) throw ProtocolError("bad_lamp", Printable(word));
  return *lamp;
}

bool ParseBit(std::string_view word, std::string_view line) {
  if (word == "1") return true;
  if (word == "0") return false;
  throw ProtocolError("bad_value", "'" + Printable(line) + "' (lamp states are 0 or 1)");
}

// One word of [a-z0-9_], as codes and reasons are.
bool IsWord(std::string_view word) {
  if (word.empty()) return false;
  for (const char c : word) {
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
  }
  return true;
}

}  // namespace

std::optional<Aspect> AspectFromName(std::string_view name) {
  for (std::int32_t v = 0; v <= 5; ++v) {
    const Aspect a = *AspectFromWire(v);
    if (ToString(a) == name) return a;
  }
  return std::nullopt;
}

std::string Format(const HostCommand& command) {
  return std::visit(internal::Overloaded{
                        [](const Ping&) -> std::string { return "PING"; },
                        [](const Set& s) { return "SET " + std::string(ToString(s.aspect)); },
                        [](const Flash& f) { return "FLASH " + std::to_string(f.period_ms); },
                    },
                    command);
}

std::string Format(const McuReport& report) {
  return std::visit(
      internal::Overloaded{
          [](const Hello& h) { return "HELLO " + h.protocol; },
          [](const Ok& o) { return "OK " + o.command; },
          [](const Err& e) { return "ERR " + e.code + (e.text.empty() ? "" : " " + e.text); },
          [](const LampsReport& l) {
            return std::string("LAMPS ") + (l.lamps.red ? "1" : "0") + " " +
                   (l.lamps.yellow ? "1" : "0") + " " + (l.lamps.green ? "1" : "0");
          },
          [](const Fault& f) { return "FAULT " + std::string(ToString(f.lamp)) + " " + f.reason; },
          [](const Clear& c) { return "CLEAR " + std::string(ToString(c.lamp)); },
          [](const Watchdog&) -> std::string { return "WATCHDOG"; },
      },
      report);
}

HostCommand ParseHostCommand(std::string_view line) {
  if (line.size() > kMaxLineLength) throw ProtocolError("malformed", "line too long");
  const auto words = Words(line);
  const std::string_view verb = words[0];
  if (verb == "PING") {
    ExpectWords(words, 1, line);
    return Ping{};
  }
  if (verb == "SET") {
    ExpectWords(words, 2, line);
    const auto aspect = AspectFromName(words[1]);
    if (!aspect) throw ProtocolError("bad_aspect", Printable(words[1]));
    return Set{*aspect};
  }
  if (verb == "FLASH") {
    ExpectWords(words, 2, line);
    const auto ms = ParseInt(words[1]);
    if (!ms || *ms < kMinFlashPeriodMs || *ms > kMaxFlashPeriodMs) {
      throw ProtocolError("bad_value", Printable(words[1]) + " (flash period in ms, " +
                                           std::to_string(kMinFlashPeriodMs) + ".." +
                                           std::to_string(kMaxFlashPeriodMs) + ")");
    }
    return Flash{*ms};
  }
  throw ProtocolError("unknown_command", Printable(verb));
}

McuReport ParseMcuReport(std::string_view line) {
  if (line.size() > kMaxLineLength) throw ProtocolError("malformed", "line too long");
  const auto words = Words(line);
  const std::string_view verb = words[0];
  if (verb == "HELLO") {
    ExpectWords(words, 2, line);
    return Hello{std::string(words[1])};
  }
  if (verb == "OK") {
    if (words.size() < 2) throw ProtocolError("malformed", "'" + Printable(line) + "'");
    return Ok{std::string(line.substr(3))};
  }
  if (verb == "ERR") {
    if (words.size() < 2 || !IsWord(words[1])) {
      throw ProtocolError("malformed", "'" + Printable(line) + "'");
    }
    const std::size_t text_start = 4 + words[1].size() + 1;
    return Err{std::string(words[1]),
               text_start < line.size() ? Printable(line.substr(text_start)) : std::string()};
  }
  if (verb == "LAMPS") {
    ExpectWords(words, 4, line);
    LampsReport r;
    r.lamps.red = ParseBit(words[1], line);
    r.lamps.yellow = ParseBit(words[2], line);
    r.lamps.green = ParseBit(words[3], line);
    return r;
  }
  if (verb == "FAULT") {
    ExpectWords(words, 3, line);
    if (!IsWord(words[2])) throw ProtocolError("malformed", "'" + Printable(line) + "'");
    return Fault{ParseLamp(words[1]), std::string(words[2])};
  }
  if (verb == "CLEAR") {
    ExpectWords(words, 2, line);
    return Clear{ParseLamp(words[1])};
  }
  if (verb == "WATCHDOG") {
    ExpectWords(words, 1, line);
    return Watchdog{};
  }
  throw ProtocolError("unknown_command", Printable(verb));
}

void LineSplitter::Append(std::string_view bytes) {
  for (const char c : bytes) {
    if (c == '\n') {
      if (discarding_) {  // the end of an overlong line: drop it, keep earlier lines
        discarding_ = false;
        continue;
      }
      if (!buffer_.empty() && buffer_.back() == '\r') buffer_.pop_back();
      buffer_ += '\n';  // marks a complete line; taken by Next()
      continue;
    }
    if (discarding_) continue;
    // Length of the line being received: after the last complete one.
    const std::size_t last_nl = buffer_.rfind('\n');
    const std::size_t current =
        last_nl == std::string::npos ? buffer_.size() : buffer_.size() - last_nl - 1;
    if (current >= kMaxLineLength + 1) {  // room for a trailing '\r'
      buffer_.resize(buffer_.size() - current);
      discarding_ = true;
      ++overlong_;
      continue;
    }
    buffer_ += c;
  }
}

std::optional<std::string> LineSplitter::Next() {
  const std::size_t nl = buffer_.find('\n');
  if (nl == std::string::npos) return std::nullopt;
  std::string line = buffer_.substr(0, nl);
  buffer_.erase(0, nl + 1);
  return line;
}

void LineSplitter::Clear() {
  buffer_.clear();
  discarding_ = false;
}

}  // namespace autodrive::infrastructure::serial
