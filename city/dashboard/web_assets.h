#pragma once
/// @file
/// The page's files (city/dashboard/web/), compiled into the program by CMake
/// (embed_web.cmake): the dashboard needs no files at run time.

#include <span>
#include <string_view>

namespace autodrive::dashboard {

struct WebAsset {
  std::string_view path;  ///< URL path: "/", "/app.js", "/style.css"
  std::string_view mime;  ///< text/html, text/javascript, text/css (all UTF-8)
  std::string_view content;
};

/// Every file of the page.
[[nodiscard]] std::span<const WebAsset> WebAssets();

}  // namespace autodrive::dashboard
