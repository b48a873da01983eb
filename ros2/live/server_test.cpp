#include "ros2/live/server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>

#include "common/error.h"

namespace autodrive::ros2::live {
namespace {

using namespace std::chrono_literals;
namespace net = boost::asio;
using tcp = net::ip::tcp;

TEST(SetListenAddress, ReadsHostAndPort) {
  ServerOptions o;
  SetListenAddress("0.0.0.0:0", o);
  EXPECT_EQ(o.host, "0.0.0.0");
  EXPECT_EQ(o.port, 0);
  SetListenAddress("[::1]:8765", o);
  EXPECT_EQ(o.host, "::1");
  EXPECT_EQ(o.port, 8765);
}

TEST(SetListenAddress, RefusesOtherFormsNamingThem) {
  ServerOptions o;
  const auto message = [&](std::string_view text) {
    try {
      SetListenAddress(text, o);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_NE(message("8765").find("--address must be HOST:PORT, got '8765'"), std::string::npos);
  EXPECT_NE(message(":8765").find("must be HOST:PORT"), std::string::npos);
  EXPECT_NE(message("localhost:").find("must be HOST:PORT"), std::string::npos);
  EXPECT_NE(message("127.0.0.1:65536").find("the port must be 0..65535, got '65536'"),
            std::string::npos);
  EXPECT_NE(message("127.0.0.1:80x").find("got '80x'"), std::string::npos);
}

/// Keeps the connections it is given; counts closes.
class Recorder final : public ConnectionHandler {
 public:
  void OnOpen(const std::shared_ptr<Connection>& c) override {
    std::lock_guard lock(mutex_);
    open_.push_back(c);
    cv_.notify_all();
  }
  void OnText(const std::shared_ptr<Connection>& c, std::string_view text) override {
    c->Send(OutFrame::Text("echo " + std::string(text)));
  }
  void OnBinary(const std::shared_ptr<Connection>&, std::span<const std::byte>) override {}
  void OnClose(const std::shared_ptr<Connection>&) override {
    std::lock_guard lock(mutex_);
    ++closed_;
    cv_.notify_all();
  }
  std::shared_ptr<Connection> WaitOpen() {
    std::unique_lock lock(mutex_);
    cv_.wait_for(lock, 30s, [&] { return !open_.empty(); });
    return open_.empty() ? nullptr : open_.front();
  }
  bool WaitClosed(int n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, 30s, [&] { return closed_ >= n; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<std::shared_ptr<Connection>> open_;
  int closed_ = 0;
};

/// A GET with `headers` on a new connection; the answer's head, and the socket.
std::string Request(net::io_context& io, std::uint16_t port, const std::string& headers,
                    tcp::socket& socket, net::streambuf& buffer) {
  socket = tcp::socket(io);
  socket.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
  net::write(socket, net::buffer("GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n" + headers + "\r\n"));
  const std::size_t n = net::read_until(socket, buffer, "\r\n\r\n");
  std::string head(net::buffers_begin(buffer.data()), net::buffers_end(buffer.data()));
  head.resize(n);
  buffer.consume(n);
  return head;
}

const std::string kUpgrade =
    "Connection: Upgrade\r\nUpgrade: websocket\r\nSec-WebSocket-Version: 13\r\n"
    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";

TEST(WebSocketServer, RefusesPlainHttpAndUpgradesWithoutAFoxgloveSubprotocol) {
  Recorder handler;
  WebSocketServer server({"127.0.0.1", 0}, handler);
  server.Start();
  ASSERT_NE(server.port(), 0);
  net::io_context io;
  tcp::socket socket(io);
  net::streambuf buffer;
  for (const std::string& headers :
       {std::string(), kUpgrade, kUpgrade + "Sec-WebSocket-Protocol: chat\r\n"}) {
    const std::string head = Request(io, server.port(), headers, socket, buffer);
    EXPECT_EQ(head.rfind("HTTP/1.1 400 Bad Request\r\n", 0), 0U) << head;
    boost::system::error_code ec;
    net::read(socket, buffer, ec);  // the body, to the close
    const std::string body(net::buffers_begin(buffer.data()), net::buffers_end(buffer.data()));
    buffer.consume(buffer.size());
    EXPECT_NE(body.find("foxglove.websocket.v1"), std::string::npos) << body;
  }
  const std::string head =
      Request(io, server.port(), kUpgrade + "Sec-WebSocket-Protocol: chat, foxglove.sdk.v1\r\n",
              socket, buffer);
  EXPECT_EQ(head.rfind("HTTP/1.1 101", 0), 0U) << head;
  EXPECT_NE(head.find("Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n"), std::string::npos) << head;
  const auto connection = handler.WaitOpen();
  ASSERT_NE(connection, nullptr);
  EXPECT_EQ(connection->subprotocol(), "foxglove.sdk.v1");
  // A text frame from the server: FIN + text, unmasked, its length, the text.
  connection->Send(OutFrame::Text("hello"));
  net::read(socket, buffer, net::transfer_at_least(7));
  std::string frame(net::buffers_begin(buffer.data()), net::buffers_end(buffer.data()));
  frame.resize(7);
  EXPECT_EQ(frame, std::string("\x81\x05hello"));
  socket.close();
  EXPECT_TRUE(handler.WaitClosed(1));
}

TEST(WebSocketServer, SendToAClientThatStopsReadingNeverBlocksAndDropsBeyondTheBound) {
  Recorder handler;
  ServerOptions options{"127.0.0.1", 0};
  options.client_queue_bytes = 1 << 20;
  WebSocketServer server(options, handler);
  server.Start();
  net::io_context io;
  tcp::socket socket(io);
  net::streambuf buffer;
  const std::string head =
      Request(io, server.port(), kUpgrade + "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n",
              socket, buffer);
  ASSERT_EQ(head.rfind("HTTP/1.1 101", 0), 0U) << head;
  const auto connection = handler.WaitOpen();
  ASSERT_NE(connection, nullptr);
  // 50 MB for a client that reads nothing: far more than the socket buffers take. Each Send
  // returns at once (a blocking one would hang this loop, and the test would time out).
  auto payload = std::make_shared<const std::vector<std::byte>>(std::size_t{256} << 10);
  for (std::uint32_t i = 0; i < 200; ++i) {
    connection->Send(OutFrame::Data(EncodeMessageDataHeader(i, 0), payload));
  }
  const ConnectionStats stats = connection->stats();
  EXPECT_GT(stats.dropped_frames, 100U);
  EXPECT_LE(stats.queued_bytes, options.client_queue_bytes);
  server.Stop();
  EXPECT_TRUE(handler.WaitClosed(1)) << "Stop closes every connection";
}

}  // namespace
}  // namespace autodrive::ros2::live
