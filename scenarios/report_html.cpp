#include "scenarios/report_html.h"

#include <string_view>

#include "scenarios/internal/report_assets.h"
#include "scenarios/internal/report_data.h"

namespace autodrive::scenarios {

namespace {

using nlohmann::json;

std::string EscapeHtml(std::string_view text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// The data as the text of a <script type="application/json">: every '<' written as \u003c
// (valid JSON, read back the same), so that no "</script" or "<!--" in a string (a log's
// message, a file's text) can end or change the element. Bytes that are not UTF-8 are replaced.
std::string EmbeddedJson(const json& data) {
  const std::string text = data.dump(-1, ' ', false, json::error_handler_t::replace);
  std::string out;
  out.reserve(text.size() + 64);
  for (const char c : text) {
    if (c == '<') {
      out += "\\u003c";
    } else {
      out += c;
    }
  }
  return out;
}

// The page: nothing but inline style, data and scripts. The Content-Security-Policy lets the
// page load nothing at all (no image, font, frame or fetch), so that a change that adds a URL
// fails in the browser test instead of reaching out when the page is opened.
std::string Page(const std::string& title, const std::string& body_class, const json& data,
                 const std::string& script) {
  const internal::ReportAssetTexts& a = internal::ReportAssets();
  std::string page;
  page.reserve(a.uplot_js.size() + a.uplot_css.size() + a.page_css.size() + a.common_js.size() +
               script.size() + 4096);
  page += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  page +=
      "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
      "script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:\">\n";
  page += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
  page += "<meta name=\"generator\" content=\"autodrive-scenario\">\n";
  page += "<title>" + EscapeHtml(title) + "</title>\n";
  page += "<link rel=\"icon\" href=\"data:,\">\n";
  page += "<style>\n" + a.uplot_css + "\n</style>\n";
  page += "<style>\n" + a.page_css + "\n</style>\n";
  page += "</head>\n<body class=\"" + body_class + "\">\n";
  page +=
      "<noscript>This page draws itself with JavaScript (inline; it loads nothing). Its data "
      "is in the JSON below and in the files beside it.</noscript>\n";
  page += "<main id=\"page\"></main>\n";
  page +=
      "<script type=\"application/json\" id=\"page-data\">" + EmbeddedJson(data) + "</script>\n";
  page += "<script>\n" + a.uplot_js + "\n</script>\n";
  page += "<script>\n" + a.common_js + "\n</script>\n";
  page += "<script>\n" + script + "\n</script>\n";
  page += "</body>\n</html>\n";
  return page;
}

std::string NameIn(const json& j, const char* object, const char* fallback) {
  if (j.contains(object) && j[object].is_object() && j[object].contains("name") &&
      j[object]["name"].is_string()) {
    return j[object]["name"].get<std::string>();
  }
  return fallback;
}

}  // namespace

std::string ReportHtml(const json& report, const std::filesystem::path& run_dir) {
  const json data = internal::ReportPageData(report, run_dir);
  const bool passed = report.contains("passed") && report["passed"] == true;
  return Page(NameIn(report, "scenario", "scenario") + (passed ? " — passed" : " — FAILED"),
              "report", data, internal::ReportAssets().report_js);
}

std::string SummaryHtml(const json& summary) {
  const json data = internal::SummaryPageData(summary);
  return Page(NameIn(summary, "sweep", "sweep") + " — sweep summary", "summary", data,
              internal::ReportAssets().summary_js);
}

}  // namespace autodrive::scenarios
