#include "ros2/live/server.h"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/read_until.hpp>
#include <boost/asio/streambuf.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket.hpp>

#include "common/error.h"

namespace autodrive::ros2::live {
namespace {

using namespace std::chrono_literals;
namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
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

// Frames sent faster than one write each (the write chain gathers the small ones under the
// WebSocket and sends them together, ros2/live/server.cpp): every message arrives whole, in
// order, as its own WebSocket message, the small and the large (written alone), text among
// them, while the client's pings are answered in between.
TEST(WebSocketServer, FramesSentInABurstArriveWholeInOrderEachAsItsOwnMessage) {
  Recorder handler;
  ServerOptions options{"127.0.0.1", 0};
  options.client_queue_bytes = std::size_t{64} << 20;  // room for all: nothing is dropped
  WebSocketServer server(options, handler);
  server.Start();
  net::io_context io;
  websocket::stream<tcp::socket> client(io);
  client.next_layer().connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), server.port()));
  client.set_option(websocket::stream_base::decorator([](websocket::request_type& request) {
    request.set(beast::http::field::sec_websocket_protocol, "foxglove.websocket.v1");
  }));
  client.handshake("127.0.0.1", "/");
  const auto connection = handler.WaitOpen();
  ASSERT_NE(connection, nullptr);
  // Sizes from 1 byte to 100 KB (past the 64 KB that are gathered), every tenth a text frame.
  constexpr std::uint32_t kFrames = 3000;
  const auto size_of = [](std::uint32_t i) { return std::size_t{1} + (i * 7919U) % 100000U; };
  std::thread sender([&] {
    for (std::uint32_t i = 0; i < kFrames; ++i) {
      if (i % 10 == 0) {
        connection->Send(OutFrame::Text("text " + std::to_string(i)));
        continue;
      }
      auto payload = std::make_shared<std::vector<std::byte>>(size_of(i));
      for (std::size_t b = 0; b < payload->size(); ++b) {
        (*payload)[b] = static_cast<std::byte>((i + b) % 251U);
      }
      connection->Send(OutFrame::Data(EncodeMessageDataHeader(i, i), std::move(payload)));
    }
  });
  std::uint32_t wrong = 0;
  for (std::uint32_t i = 0; i < kFrames; ++i) {
    if (i % 500 == 250) client.ping({});  // its pong comes among the frames
    beast::flat_buffer message;
    client.read(message);
    const auto* data = static_cast<const std::byte*>(message.data().data());
    const std::span<const std::byte> bytes(data, message.size());
    if (i % 10 == 0) {
      const std::string text(reinterpret_cast<const char*>(data), message.size());
      if (!client.got_text() || text != "text " + std::to_string(i)) {
        ADD_FAILURE() << "message " << i << ": " << text.substr(0, 40);
        if (++wrong > 5) break;
      }
      continue;
    }
    const std::optional<MessageData> m = DecodeMessageData(bytes);
    bool whole =
        client.got_binary() && m && m->subscription_id == i && m->payload.size() == size_of(i);
    for (std::size_t b = 0; whole && b < m->payload.size(); ++b) {
      whole = m->payload[b] == static_cast<std::byte>((i + b) % 251U);
    }
    if (!whole) {
      ADD_FAILURE() << "message " << i << " is not frame " << i << " whole ("
                    << (m ? m->subscription_id : 0) << ", " << message.size() << " bytes)";
      if (++wrong > 5) break;
    }
  }
  sender.join();
  EXPECT_EQ(connection->stats().dropped_frames, 0U);
  server.Stop();
}

}  // namespace
}  // namespace autodrive::ros2::live
