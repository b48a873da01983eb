#pragma once
/// @file
/// The live view's WebSocket server (Boost.Beast): accepts clients that offer one of the Foxglove
/// subprotocols (`kSubprotocols`), answers every other request with HTTP 400 and a body saying
/// why, and gives each client a bounded send queue (`SendQueue`).
///
/// Threads: every socket operation runs on the server's one I/O thread (asynchronous, never
/// blocking it); the `ConnectionHandler` is called there. `Connection::Send` may be called from
/// any thread (a DDS listener's): it only queues the frame and wakes the I/O thread, it never
/// touches the socket, so a client that stops reading never blocks the caller.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

#include "ros2/live/send_queue.h"

namespace autodrive::ros2::live {

/// What a connection's send queue has seen.
struct ConnectionStats {
  std::size_t queued_bytes = 0;
  std::uint64_t sent_frames = 0;
  std::uint64_t dropped_frames = 0;  ///< data frames dropped because the queue was full
};

/// One client. Shared (shared_ptr): the server's pending asynchronous operations and the
/// handler's subscriptions both keep it until the last of them lets go. Not copyable.
class Connection {
 public:
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  virtual ~Connection() = default;

  /// Queues `frame` for sending. Thread-safe; never blocks on the socket. Frames for a closed
  /// connection are discarded.
  virtual void Send(OutFrame frame) = 0;
  [[nodiscard]] virtual ConnectionStats stats() const = 0;
  /// A number unique in the server's life (1, 2, ...), for logs.
  [[nodiscard]] virtual std::uint64_t id() const = 0;
  /// "address:port" of the client.
  [[nodiscard]] virtual const std::string& remote() const = 0;
  /// The subprotocol it was accepted with.
  [[nodiscard]] virtual const std::string& subprotocol() const = 0;
};

/// What the server tells its user, on the I/O thread. Implementations must not block.
class ConnectionHandler {
 public:
  virtual ~ConnectionHandler() = default;
  /// A client completed the WebSocket handshake.
  virtual void OnOpen(const std::shared_ptr<Connection>& connection) = 0;
  virtual void OnText(const std::shared_ptr<Connection>& connection, std::string_view text) = 0;
  virtual void OnBinary(const std::shared_ptr<Connection>& connection,
                        std::span<const std::byte> data) = 0;
  /// The client went away (or the server stops); called once per opened connection.
  virtual void OnClose(const std::shared_ptr<Connection>& connection) = 0;
};

/// The server's settings.
struct ServerOptions {
  std::string host = "127.0.0.1";
  /// 0: a free port (see `WebSocketServer::port`).
  std::uint16_t port = 8765;
  /// Each client's send queue bound, bytes of message data (`SendQueue`): it must hold a camera
  /// frame (1920x1080 rgb8: 6.2 MB), which a smaller bound drops whole.
  std::size_t client_queue_bytes = std::size_t{8} << 20;
  /// The largest client message read, bytes (clients send small JSON).
  std::size_t max_client_message_bytes = std::size_t{1} << 20;
};

/// Sets `options.host` and `options.port` from "HOST:PORT" ("127.0.0.1:8765", "0.0.0.0:0",
/// "[::1]:8765"); throws `InputError` naming the text when it is not of that form or the port is
/// not 0..65535.
void SetListenAddress(std::string_view address, ServerOptions& options);

/// Listens from construction, serves from `Start` until `Stop`. Not copyable or movable.
class WebSocketServer {
 public:
  /// Binds and listens; throws `InputError` naming the address when it cannot. `handler` must
  /// outlive the server.
  WebSocketServer(ServerOptions options, ConnectionHandler& handler);
  WebSocketServer(const WebSocketServer&) = delete;
  WebSocketServer& operator=(const WebSocketServer&) = delete;
  /// Stops.
  ~WebSocketServer();

  /// The port it listens on (the one chosen when the options said 0).
  [[nodiscard]] std::uint16_t port() const;
  /// Starts the I/O thread.
  void Start();
  /// Closes every connection (each gets `OnClose`) and joins the I/O thread. Idempotent.
  void Stop();

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace autodrive::ros2::live
