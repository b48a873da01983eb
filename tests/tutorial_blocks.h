#pragma once
/// @file
/// The tutorials' own text for the tests that follow them (docs/tutorials/*.md): a fenced block
/// marked `<!-- test: NAME -->` on the line just before its opening fence is what the test runs
/// or writes, so that the tutorial and its test cannot drift apart; a quoted output with `…`
/// for the parts that vary is matched against what a program printed.
#include <ctime>
#include <string>
#include <string_view>
#include <vector>

#include "common/config.h"
#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::test {

/// The fenced block marked `<!-- test: name -->` in docs/tutorials/<tutorial>.md: its lines
/// between the fences, each ending in "\n". Throws `InputError` naming the file and the mark when
/// the mark is missing, repeated, or not followed at once by a fence that is closed.
inline std::string TutorialBlock(const std::string& tutorial, const std::string& name) {
  const auto path = SourceDir() / "docs" / "tutorials" / (tutorial + ".md");
  const std::string text = config::ReadFile(path);
  const std::string mark = "<!-- test: " + name + " -->\n";
  const auto at = text.find(mark);
  if (at == std::string::npos || text.find(mark, at + 1) != std::string::npos) {
    throw InputError(path.string() + ": " +
                     (at == std::string::npos ? "no block marked " : "two blocks marked ") + mark);
  }
  // The fence and the block's lines are indented as the mark is (a block in a list item).
  auto fence = at + mark.size();
  const auto indent = text.find_first_not_of(' ', fence) - fence;
  fence += indent;
  const auto body = text.find('\n', fence);
  if (text.compare(fence, 3, "```") != 0 || body == std::string::npos) {
    throw InputError(path.string() + ": the block marked " + name + " does not open with ```");
  }
  const std::string pad(indent, ' ');
  const auto end = text.find("\n" + pad + "```", body);
  if (end == std::string::npos) {
    throw InputError(path.string() + ": the block marked " + name + " is not closed");
  }
  std::string out;
  for (auto line = body + 1; line <= end;) {
    const auto eol = text.find('\n', line);
    const auto skip = text.compare(line, indent, pad) == 0 ? indent : 0;
    out += text.substr(line + skip, eol + 1 - line - skip);
    line = eol + 1;
  }
  return out;
}

/// `text` with a tutorial's diff block (lines " context", "-gone", "+new") applied at the first
/// place its context and gone lines stand together. Throws `InputError` when they stand nowhere.
inline std::string ApplyDiff(std::string text, const std::string& diff) {
  std::string from, to;
  for (std::size_t line = 0; line < diff.size();) {
    const auto eol = diff.find('\n', line);
    const std::string rest = diff.substr(line + 1, eol - line);
    if (diff[line] != '+') from += rest;
    if (diff[line] != '-') to += rest;
    line = eol + 1;
  }
  const auto at = text.find(from);
  if (at == std::string::npos) throw InputError("the diff's lines are not in the file:\n" + from);
  return text.replace(at, from.size(), to);
}

/// `text` with every run of spaces, tabs and line ends made one space, trimmed.
inline std::string OneLine(std::string_view text) {
  std::string out;
  for (const char c : text) {
    const bool space = c == ' ' || c == '\t' || c == '\n' || c == '\r';
    if (!space) {
      out += c;
    } else if (!out.empty() && out.back() != ' ') {
      out += ' ';
    }
  }
  if (!out.empty() && out.back() == ' ') out.pop_back();
  return out;
}

/// Whether `output` holds what a tutorial quotes: the parts of `quoted` between its `…` appear
/// in `output` in that order, line breaks and runs of spaces counting as one space.
inline bool ShowsQuoted(std::string_view output, std::string_view quoted) {
  const std::string out = OneLine(output);
  const std::string q(quoted);
  const std::string ellipsis = "…";
  std::size_t from = 0, pos = 0;
  for (;;) {
    const auto next = q.find(ellipsis, pos);
    const std::string part =
        OneLine(q.substr(pos, next == std::string::npos ? std::string::npos : next - pos));
    if (!part.empty()) {
      const auto found = out.find(part, from);
      if (found == std::string::npos) return false;
      from = found + part.size();
    }
    if (next == std::string::npos) return true;
    pos = next + ellipsis.size();
  }
}

/// A POSIX TZ setting ("TZ=XXX-5:15") in which the local time is now `hour`:`minute`, so that a
/// test runs the plan a city's schedule gives at that time, whatever time of day it runs at.
inline std::string TimeZoneWhereItIs(int hour, int minute) {
  const std::time_t t = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&t, &utc);
  // TZ's offset is UTC minus local time.
  const int offset = (utc.tm_hour * 60 + utc.tm_min) - (hour * 60 + minute);
  const int magnitude = offset < 0 ? -offset : offset;
  return "TZ=XXX" + std::string(offset < 0 ? "-" : "") + std::to_string(magnitude / 60) + ":" +
         (magnitude % 60 < 10 ? "0" : "") + std::to_string(magnitude % 60);
}

}  // namespace autodrive::test
