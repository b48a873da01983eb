#include "scenarios/internal/logs.h"

#include <fmt/format.h>

#include <cmath>
#include <exception>

#include "common/error.h"

namespace autodrive::scenarios::internal {

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t i = 0; i <= line.size(); ++i) {
    if (i == line.size() || line[i] == ',') {
      out.push_back(line.substr(start, i - start));
      start = i + 1;
    }
  }
  return out;
}

double Number(const std::string& s, const std::filesystem::path& file, std::size_t line) {
  try {
    std::size_t used = 0;
    const double x = std::stod(s, &used);
    if (used == s.size() && std::isfinite(x)) return x;
  } catch (const std::exception&) {
  }
  throw InputError(fmt::format("{}:{}: \"{}\" is not a number", file.string(), line, s));
}

}  // namespace autodrive::scenarios::internal
