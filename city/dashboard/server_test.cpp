// The dashboard's HTTP side with a real server and a real HTTP client (cpp-httplib's): what is
// compressed, and how.
#include "city/dashboard/server.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "city/dashboard/hub.h"
#include "city/dashboard/web_assets.h"

#include "common/dds/participant.h"

// Last: it brings <resolv.h>, whose `_res` macro breaks Eigen's headers included after it.
#include <httplib.h>

namespace autodrive::dashboard {
namespace {

using namespace std::chrono_literals;

class DashboardServer : public ::testing::Test {
 protected:
  DashboardServer()
      : participant_(
            dds::ParticipantOptions{{}, fmt::format("dashboard_server_test_{}", ::getpid()), {}}),
        server_(participant_, hub_, Options(), [] { return nlohmann::json::object(); }) {
    server_.Start();
  }
  ~DashboardServer() override { server_.Stop(); }

  static ServerOptions Options() {
    ServerOptions o;
    o.port = 0;
    // A big, repetitive map, as a grid city's is.
    o.svg = "<svg xmlns=\"http://www.w3.org/2000/svg\">";
    for (int i = 0; i < 20000; ++i) o.svg += fmt::format("<rect x=\"{}\" y=\"7\"/>", i);
    o.svg += "</svg>";
    return o;
  }

  httplib::Client Client() const {
    httplib::Client c("127.0.0.1", server_.port());
    c.set_read_timeout(30, 0);
    return c;
  }

  dds::Participant participant_;
  Hub hub_{nlohmann::json::object(), nlohmann::json::array(), /*actions_need_token=*/true};
  Server server_;
};

TEST_F(DashboardServer, ThePageIsGzippedForABrowserThatTakesItAndNeverBrotlid) {
  ASSERT_GT(server_.port(), 0);
  for (const WebAsset& asset : WebAssets()) {
    SCOPED_TRACE(std::string(asset.path));
    httplib::Client c = Client();
    // A browser's header: cpp-httplib alone would answer with brotli at its slowest quality.
    const auto gz = c.Get(std::string(asset.path), {{"Accept-Encoding", "gzip, deflate, br"}});
    ASSERT_TRUE(gz);
    EXPECT_EQ(gz->status, 200);
    EXPECT_EQ(gz->get_header_value("Content-Encoding"), "gzip");
    EXPECT_EQ(gz->body, asset.content);  // the client unzips it
    const auto br = c.Get(std::string(asset.path), {{"Accept-Encoding", "br"}});
    ASSERT_TRUE(br);
    EXPECT_FALSE(br->has_header("Content-Encoding"));
    EXPECT_EQ(br->body, asset.content);
  }
  httplib::Client c = Client();
  const auto svg = c.Get("/map.svg", {{"Accept-Encoding", "gzip, br"}});
  ASSERT_TRUE(svg);
  EXPECT_EQ(svg->get_header_value("Content-Encoding"), "gzip");
  EXPECT_EQ(svg->body, Options().svg);
}

TEST_F(DashboardServer, TheStateAndTheStreamAreNotCompressed) {
  httplib::Client c = Client();
  const auto whole = c.Get("/api/state", {{"Accept-Encoding", "gzip, deflate, br"}});
  ASSERT_TRUE(whole);
  EXPECT_EQ(whole->status, 200);
  EXPECT_FALSE(whole->has_header("Content-Encoding"));
  EXPECT_TRUE(nlohmann::json::accept(whole->body));

  // The stream: its headers and its first message (the whole state), as they come.
  std::string encoding = "unread", first;
  const auto stream = c.Get(
      "/api/stream", {{"Accept-Encoding", "gzip, deflate, br"}},
      [&](const httplib::Response& r) {
        encoding = r.get_header_value("Content-Encoding");
        return true;
      },
      [&](const char* data, std::size_t size) {
        first.append(data, size);
        // Until the first message (the whole state) is in, then stop.
        const std::size_t state = first.find("event: state\n");
        return state == std::string::npos || first.find("\n\n", state) == std::string::npos;
      });
  EXPECT_EQ(encoding, "");
  const std::size_t state = first.find("event: state\ndata: ");
  ASSERT_NE(state, std::string::npos) << first.substr(0, 80);
  const std::size_t data = state + std::string_view("event: state\ndata: ").size();
  EXPECT_TRUE(nlohmann::json::accept(first.substr(data, first.find('\n', data) - data)));
}

}  // namespace
}  // namespace autodrive::dashboard
