# Writes OUTPUT: a C++ source that defines autodrive::dashboard::WebAssets() with the bytes of
# the page's files (run by CMake at build time; inputs: OUTPUT, WEB_DIR).
set(assets
  "/|index.html|text/html"
  "/app.js|app.js|text/javascript"
  "/style.css|style.css|text/css")
set(arrays "")
set(table "")
set(i 0)
foreach(asset IN LISTS assets)
  string(REPLACE "|" ";" parts "${asset}")
  list(GET parts 0 url)
  list(GET parts 1 file)
  list(GET parts 2 mime)
  file(READ "${WEB_DIR}/${file}" hex HEX)
  string(LENGTH "${hex}" hex_length)
  math(EXPR bytes "${hex_length} / 2")
  string(REGEX REPLACE "([0-9a-f][0-9a-f])" "'\\\\x\\1'," body "${hex}")
  string(REGEX REPLACE "(([^,]*,){24})" "\\1\n" body "${body}")
  string(APPEND arrays "constexpr char kAsset${i}[] = {\n${body}'\\0'};\n")
  string(APPEND table "    {\"${url}\", \"${mime}\", std::string_view(kAsset${i}, ${bytes})},\n")
  math(EXPR i "${i} + 1")
endforeach()
file(WRITE "${OUTPUT}.tmp" "// Generated from city/dashboard/web/ by embed_web.cmake: do not edit.
#include \"city/dashboard/web_assets.h\"

#include <array>

namespace autodrive::dashboard {
namespace {
${arrays}
constexpr std::array<WebAsset, ${i}> kAssets{{
${table}}};
}  // namespace

std::span<const WebAsset> WebAssets() { return kAssets; }

}  // namespace autodrive::dashboard
")
file(COPY_FILE "${OUTPUT}.tmp" "${OUTPUT}" ONLY_IF_DIFFERENT)
file(REMOVE "${OUTPUT}.tmp")
