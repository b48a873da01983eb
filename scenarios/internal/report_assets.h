#pragma once
/// @file
/// The text of the files every report page carries inline: the vendored uPlot
/// (scenarios/vendor/uplot-1.6.32/) and the pages' own script and style
/// (scenarios/report_web/), compiled into the library by CMake
/// (scenarios/embed_report_assets.cmake): a page needs no file and no network when it opens.

#include <string>

namespace autodrive::scenarios::internal {

/// Each file's text, byte for byte. None holds the end tag of the element it goes into
/// (`</script`, `</style`): the embedding refuses such a file at build time.
struct ReportAssetTexts {
  std::string uplot_js;    ///< uPlot.iife.min.js (defines the global `uPlot`)
  std::string uplot_css;   ///< uPlot.min.css
  std::string page_css;    ///< report.css: both pages' style
  std::string common_js;   ///< common.js: colours, formats, the shared chart helpers
  std::string report_js;   ///< report.js: draws report.html from its data
  std::string summary_js;  ///< summary.js: draws summary.html from its data
};

/// The texts, made once (thread-safe).
[[nodiscard]] const ReportAssetTexts& ReportAssets();

}  // namespace autodrive::scenarios::internal
