#include "ros2/live/server.h"

#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <charconv>
#include <mutex>
#include <thread>
#include <vector>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include "common/error.h"

namespace autodrive::ros2::live {

namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

constexpr auto kHandshakeTimeout = std::chrono::seconds(30);
/// How long message data waits in a client's queue for more before its write chain starts:
/// the latency it adds (the limit, source to client p99: 50 ms).
constexpr auto kBatchWindow = std::chrono::milliseconds(5);

/// Frames of a write chain smaller than this are gathered (a camera image is written alone).
constexpr std::size_t kGatherFrameBytes = std::size_t{64} << 10;
/// A chain's gathered bytes go out once they reach this.
constexpr std::size_t kGatherBytes = std::size_t{256} << 10;

/// The TCP stream under a client's WebSocket (Beast's `websocket::stream`, which frames every
/// message): while gathering, what the WebSocket writes is kept and its write completes at
/// once; the first write after gathering stops sends the kept bytes and its own in one write.
/// The switch is flipped only between the WebSocket's writes, and a WebSocket writes one
/// message at a time, so the bytes leave in the order written (pongs and closes included).
class GatherStream {
 public:
  using executor_type = beast::tcp_stream::executor_type;

  explicit GatherStream(tcp::socket socket) : next_(std::move(socket)) {}

  executor_type get_executor() noexcept { return next_.get_executor(); }
  beast::tcp_stream& next_layer() noexcept { return next_; }
  const beast::tcp_stream& next_layer() const noexcept { return next_; }

  /// Whether writes are kept (true) or sent, with what was kept before them (false).
  void Gather(bool on) { gathering_ = on; }
  /// Bytes kept.
  [[nodiscard]] std::size_t gathered() const { return kept_.size(); }

  template <class MutableBuffers, class Handler>
  void async_read_some(const MutableBuffers& buffers, Handler&& handler) {
    next_.async_read_some(buffers, std::forward<Handler>(handler));
  }

  template <class ConstBuffers, class Handler>
  void async_write_some(const ConstBuffers& buffers, Handler&& handler) {
    if (gathering_) {
      const std::size_t n = beast::buffer_bytes(buffers);
      kept_.commit(net::buffer_copy(kept_.prepare(n), buffers));
      net::post(next_.get_executor(),
                beast::bind_front_handler(std::forward<Handler>(handler), beast::error_code{}, n));
      return;
    }
    if (kept_.size() == 0) {
      next_.async_write_some(buffers, std::forward<Handler>(handler));
      return;
    }
    // The kept bytes move to the write (it may outlive this stream: a pending write completes,
    // aborted, after the WebSocket that owned the stream is gone).
    auto kept = std::make_shared<beast::flat_buffer>(std::move(kept_));
    kept_ = beast::flat_buffer();
    net::async_write(next_, beast::buffers_cat(kept->data(), buffers),
                     [kept, handler = std::forward<Handler>(handler)](beast::error_code ec,
                                                                      std::size_t written) mutable {
                       const std::size_t before = kept->size();
                       std::move(handler)(ec, written > before ? written - before : 0);
                     });
  }

 private:
  beast::tcp_stream next_;
  beast::flat_buffer kept_;
  bool gathering_ = false;
};

// What Beast's WebSocket calls to close: the TCP stream's (the server closes asynchronously
// only, so the blocking `teardown` is not needed).
template <class Handler>
void async_teardown(beast::role_type role, GatherStream& stream, Handler&& handler) {
  using beast::websocket::async_teardown;
  async_teardown(role, stream.next_layer().socket(), std::forward<Handler>(handler));
}

/// One client: the HTTP request, then the WebSocket, its read loop and its write chain.
class Session final : public Connection, public std::enable_shared_from_this<Session> {
 public:
  Session(tcp::socket socket, std::uint64_t id, const ServerOptions& options,
          ConnectionHandler& handler)
      : ws_(std::make_unique<websocket::stream<GatherStream>>(std::move(socket))),
        executor_(ws_->get_executor()),
        id_(id),
        handler_(handler),
        max_message_(options.max_client_message_bytes),
        queue_(options.client_queue_bytes) {
    beast::error_code ec;
    const auto endpoint = beast::get_lowest_layer(*ws_).socket().remote_endpoint(ec);
    remote_ = ec ? "?" : endpoint.address().to_string() + ":" + std::to_string(endpoint.port());
  }

  void Run() {
    beast::get_lowest_layer(*ws_).expires_after(kHandshakeTimeout);
    http::async_read(
        beast::get_lowest_layer(*ws_), buffer_, request_,
        [self = shared_from_this()](beast::error_code ec, std::size_t) { self->OnRequest(ec); });
  }

  void Send(OutFrame frame) override {
    const bool binary = frame.binary;
    bool start = false;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      queue_.Push(std::move(frame));
      start = !writing_;
      writing_ = true;
    }
    if (!start) return;
    if (!binary) {
      net::post(executor_, [self = shared_from_this()] { self->WriteNext(); });
      return;
    }
    // Message data waits up to kBatchWindow for the samples that follow it: one wake of the I/O
    // thread per window, not one per sample (10 clients on every topic: ~20,000 frames/s).
    net::post(executor_, [self = shared_from_this()] {
      if (!self->ws_) return;  // shut down meanwhile
      self->batch_timer_->expires_after(kBatchWindow);
      self->batch_timer_->async_wait([self](beast::error_code) { self->WriteNext(); });
    });
  }

  [[nodiscard]] ConnectionStats stats() const override {
    std::lock_guard lock(mutex_);
    return {queue_.bytes(), sent_, queue_.dropped()};
  }
  [[nodiscard]] std::uint64_t id() const override { return id_; }
  [[nodiscard]] const std::string& remote() const override { return remote_; }
  [[nodiscard]] const std::string& subprotocol() const override { return subprotocol_; }

  /// When the server stops (I/O thread): closes the socket, tells the handler, and deletes the
  /// stream.
  void Shutdown() {
    batch_timer_.reset();  // of the server's I/O context, as the stream (below)
    beast::error_code ec;
    beast::get_lowest_layer(*ws_).socket().shutdown(tcp::socket::shutdown_both, ec);
    beast::get_lowest_layer(*ws_).close();
    Close();
    ws_.reset();
  }

 private:
  void OnRequest(beast::error_code ec) {
    if (ec) return;  // closed before a whole request: nothing was opened
    std::vector<std::string_view> offered;
    const auto [first, last] = request_.equal_range(http::field::sec_websocket_protocol);
    for (auto field = first; field != last; ++field) {
      offered.emplace_back(field->value().data(), field->value().size());
    }
    const std::optional<std::string> chosen = ChooseSubprotocol(offered);
    if (!websocket::is_upgrade(request_)) {
      Refuse(
          "autodrive-live serves the Foxglove WebSocket protocol only: connect with a WebSocket "
          "client offering the subprotocol foxglove.websocket.v1 or foxglove.sdk.v1 (Lichtblick: "
          "Open connection, Foxglove WebSocket, ws://HOST:PORT)\n");
      return;
    }
    if (!chosen) {
      std::string text = "autodrive-live: no supported WebSocket subprotocol offered (got '";
      for (std::size_t i = 0; i < offered.size(); ++i) {
        text += (i ? ", " : "") + std::string(offered[i]);
      }
      Refuse(text + "'); offer foxglove.websocket.v1 or foxglove.sdk.v1\n");
      return;
    }
    subprotocol_ = *chosen;
    beast::get_lowest_layer(*ws_).expires_never();
    beast::get_lowest_layer(*ws_).socket().set_option(tcp::no_delay(true), ec);
    ws_->set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_->set_option(websocket::stream_base::decorator(
        [protocol = subprotocol_](websocket::response_type& response) {
          response.set(http::field::server, "autodrive-live");
          response.set(http::field::sec_websocket_protocol, protocol);
        }));
    ws_->read_message_max(max_message_);
    // One frame per message, written from the queued buffers as they are (Beast would otherwise
    // split a message into frames of its 4 KB write buffer: more copies and more system calls).
    ws_->auto_fragment(false);
    ws_->async_accept(request_, [self = shared_from_this()](beast::error_code accept_ec) {
      self->OnAccept(accept_ec);
    });
  }

  void Refuse(std::string body) {
    auto response = std::make_shared<http::response<http::string_body>>(http::status::bad_request,
                                                                        request_.version());
    response->set(http::field::server, "autodrive-live");
    response->set(http::field::content_type, "text/plain; charset=utf-8");
    response->keep_alive(false);
    response->body() = std::move(body);
    response->prepare_payload();
    http::async_write(beast::get_lowest_layer(*ws_), *response,
                      [self = shared_from_this(), response](beast::error_code, std::size_t) {
                        beast::error_code ignored;
                        beast::get_lowest_layer(*self->ws_)
                            .socket()
                            .shutdown(tcp::socket::shutdown_send, ignored);
                      });
  }

  void OnAccept(beast::error_code ec) {
    if (ec) return;
    opened_ = true;
    handler_.OnOpen(shared_from_this());
    Read();
  }

  void Read() {
    ws_->async_read(read_buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->OnRead(ec);
    });
  }

  void OnRead(beast::error_code ec) {
    if (ec) {
      Close();
      return;
    }
    const auto data = read_buffer_.cdata();
    if (ws_->got_text()) {
      handler_.OnText(shared_from_this(),
                      std::string_view(static_cast<const char*>(data.data()), data.size()));
    } else {
      handler_.OnBinary(
          shared_from_this(),
          std::span<const std::byte>(static_cast<const std::byte*>(data.data()), data.size()));
    }
    read_buffer_.consume(read_buffer_.size());
    Read();
  }

  // The write chain, on the I/O thread: one frame at a time until the queue is empty.
  void WriteNext() {
    bool more = false;
    {
      std::lock_guard lock(mutex_);
      std::optional<OutFrame> next = closed_ ? std::nullopt : queue_.Pop();
      if (!next && !closed_ && ws_->next_layer().gathered() > 0) {
        // Kept bytes with no frame left to carry them (the queue dropped it): a ping, which
        // the client answers and ignores, takes them out.
        ws_->next_layer().Gather(false);
        ws_->async_ping({},
                        [self = shared_from_this()](beast::error_code ec) { self->OnWritten(ec); });
        return;
      }
      if (!next) {
        writing_ = false;
        return;
      }
      current_ = std::move(*next);
      more = !queue_.empty();
    }
    // More behind a small frame: it is gathered, and goes out with the last of them in one
    // write (one system call for the chain, not one per frame).
    GatherStream& out = ws_->next_layer();
    out.Gather(more && current_.size() <= kGatherFrameBytes &&
               out.gathered() + current_.size() <= kGatherBytes);
    auto done = [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->OnWritten(ec);
    };
    if (current_.binary) {
      ws_->binary(true);
      const std::array<net::const_buffer, 2> buffers = {
          net::buffer(current_.header.data(), current_.header.size()),
          net::buffer(current_.payload->data(), current_.payload->size())};
      ws_->async_write(buffers, std::move(done));
    } else {
      ws_->text(true);
      ws_->async_write(net::buffer(current_.text), std::move(done));
    }
  }

  void OnWritten(beast::error_code ec) {
    current_ = OutFrame{};  // the payload is no longer needed
    if (ec) {
      {
        std::lock_guard lock(mutex_);
        writing_ = false;
      }
      Close();
      return;
    }
    {
      std::lock_guard lock(mutex_);
      ++sent_;
    }
    WriteNext();
  }

  // Once: the queue is emptied and the handler told.
  void Close() {
    {
      std::lock_guard lock(mutex_);
      if (closed_) return;
      closed_ = true;
      while (queue_.Pop()) {
      }
    }
    if (opened_) handler_.OnClose(shared_from_this());
  }

  // Deleted by Shutdown: a session that a handler keeps after the server is gone holds nothing
  // of the server's I/O context (its pending operations keep what they use).
  std::unique_ptr<websocket::stream<GatherStream>> ws_;
  websocket::stream<GatherStream>::executor_type executor_;  // Send's way to the I/O thread
  std::uint64_t id_ = 0;
  ConnectionHandler& handler_;
  std::string remote_;
  std::string subprotocol_;
  beast::flat_buffer buffer_;
  http::request<http::string_body> request_;
  beast::flat_buffer read_buffer_;
  std::size_t max_message_ = 0;
  bool opened_ = false;  // I/O thread only
  OutFrame current_;     // the frame being written; I/O thread only
  // Delays a write chain of message data; deleted by Shutdown with the stream.
  std::unique_ptr<net::steady_timer> batch_timer_ = std::make_unique<net::steady_timer>(executor_);

  mutable std::mutex mutex_;  // guards the members below
  SendQueue queue_;
  bool writing_ = false;  // a write chain is running or posted
  bool closed_ = false;
  std::uint64_t sent_ = 0;
};

}  // namespace

void SetListenAddress(std::string_view address, ServerOptions& options) {
  const auto colon = address.rfind(':');
  AUTODRIVE_THROW_UNLESS(colon != std::string_view::npos && colon > 0 && colon + 1 < address.size(),
                         "--address must be HOST:PORT, got '" << address << "'");
  const std::string_view port = address.substr(colon + 1);
  unsigned value = 0;
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
  AUTODRIVE_THROW_UNLESS(ec == std::errc() && end == port.data() + port.size() && value <= 65535,
                         "--address: the port must be 0..65535, got '" << port << "'");
  std::string_view host = address.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);  // [::1]:8765
  }
  options.host = std::string(host);
  options.port = static_cast<std::uint16_t>(value);
}

class WebSocketServer::Impl {
 public:
  Impl(ServerOptions options, ConnectionHandler& handler)
      : options_(std::move(options)), handler_(handler), acceptor_(io_) {
    beast::error_code ec;
    const auto address = net::ip::make_address(options_.host, ec);
    AUTODRIVE_THROW_UNLESS(
        !ec, "listen address '" << options_.host << "' is not an IP address: " << ec.message());
    const tcp::endpoint endpoint(address, options_.port);
    acceptor_.open(endpoint.protocol(), ec);
    if (!ec) acceptor_.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor_.bind(endpoint, ec);
    if (!ec) acceptor_.listen(net::socket_base::max_listen_connections, ec);
    AUTODRIVE_THROW_UNLESS(
        !ec, "cannot listen on " << options_.host << ":" << options_.port << ": " << ec.message());
    port_ = acceptor_.local_endpoint().port();
  }

  void Start() {
    Accept();
    thread_ = std::thread([this] { io_.run(); });
  }

  void Stop() {
    if (!thread_.joinable()) return;
    // Pending operations are abandoned; their handlers go with the context.
    net::post(io_, [this] {
      beast::error_code ec;
      acceptor_.close(ec);
      for (auto& weak : sessions_) {
        if (auto s = weak.lock()) s->Shutdown();
      }
      sessions_.clear();
      io_.stop();
    });
    thread_.join();
  }

  std::uint16_t port_ = 0;

 private:
  void Accept() {
    acceptor_.async_accept(io_.get_executor(), [this](beast::error_code ec, tcp::socket socket) {
      if (ec) {
        if (ec == net::error::operation_aborted) return;
        spdlog::warn("autodrive-live: accept: {}", ec.message());
      } else {
        auto session = std::make_shared<Session>(std::move(socket), ++next_id_, options_, handler_);
        // Forget sessions that have ended, now and then.
        if (sessions_.size() >= 64) {
          std::erase_if(sessions_, [](const std::weak_ptr<Session>& w) { return w.expired(); });
        }
        sessions_.push_back(session);
        session->Run();
      }
      Accept();
    });
  }

  ServerOptions options_;
  ConnectionHandler& handler_;
  net::io_context io_{1};
  tcp::acceptor acceptor_;
  std::vector<std::weak_ptr<Session>> sessions_;  // I/O thread only
  std::uint64_t next_id_ = 0;
  std::thread thread_;
};

WebSocketServer::WebSocketServer(ServerOptions options, ConnectionHandler& handler)
    : impl_(std::make_unique<Impl>(std::move(options), handler)) {}

WebSocketServer::~WebSocketServer() { Stop(); }

std::uint16_t WebSocketServer::port() const { return impl_->port_; }

void WebSocketServer::Start() { impl_->Start(); }

void WebSocketServer::Stop() { impl_->Stop(); }

}  // namespace autodrive::ros2::live
