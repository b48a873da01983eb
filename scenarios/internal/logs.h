#pragma once
/// @file
/// Reading the run folder's CSV logs (docs/scenarios.md, "The run folder"): what the metrics
/// and the report page share.

#include <filesystem>
#include <string>
#include <vector>

namespace autodrive::scenarios::internal {

/// The fields of one CSV line (the logs quote nothing: no field holds a comma).
[[nodiscard]] std::vector<std::string> SplitCsv(const std::string& line);

/// A finite number, else InputError naming the file, line and text.
[[nodiscard]] double Number(const std::string& s, const std::filesystem::path& file,
                            std::size_t line);

}  // namespace autodrive::scenarios::internal
