#pragma once
/// @file
/// The live view of autodrive-live: the city's topics offered to Foxglove WebSocket clients
/// (Lichtblick). It advertises every topic that has a DDS writer (found as the recorder finds
/// them, DCPSPublication), reads a topic only while a client subscribes to it (one raw reader
/// per topic, made on the first subscription and deleted on the last unsubscription or
/// disconnection) and forwards each sample's serialized bytes unchanged (encapsulation header
/// included, Foxglove's `cdr`) with the time this process received it (the messageData
/// timestamp: the protocol's "receive timestamp", on the system clock, ns since the Unix
/// epoch). Read-only: clients cannot publish, set parameters or call services.
///
/// Threads: `OnOpen`/`OnText`/`OnBinary`/`OnClose` run on the server's I/O thread, `Discover`
/// on the caller's, the forwarding on Cyclone's listener threads. A listener only queues frames
/// (`Connection::Send`), it never waits for a socket.

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "ros2/live/protocol.h"
#include "ros2/live/server.h"
#include "ros2/record/rosbag2.h"

#include "common/dds/discovery.h"
#include "common/dds/participant.h"
#include "common/dds/raw.h"

namespace autodrive::ros2::live {

/// The live view's settings.
struct LiveOptions {
  /// The name in serverInfo.
  std::string server_name = "autodrive-live";
  /// serverInfo metadata (Lichtblick reads ROS_DISTRO to pick its ROS 2 profile).
  std::vector<std::pair<std::string, std::string>> metadata;
  /// Each topic reader's history (keep last): what waits if a listener falls behind.
  std::int32_t reader_depth = 10;
};

/// One client, for logs.
struct ClientInfo {
  std::uint64_t id = 0;
  std::string remote;
  std::size_t subscriptions = 0;
  ConnectionStats stats;
};

/// Serves one participant's topics to the server's connections. Not copyable or movable.
class LiveView final : public ConnectionHandler {
 public:
  LiveView(const dds::Participant& participant, LiveOptions options);
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;
  /// Deletes the readers (waiting for running listeners).
  ~LiveView() override;

  /// Takes the writers that appeared or went since the last call; advertises the topics that
  /// got their first writer and unadvertises those that lost their last (ending their
  /// subscriptions). Call it periodically.
  void Discover();

  /// The advertised channels, by id.
  [[nodiscard]] std::vector<Channel> channels() const;
  /// Topics read now (one DDS reader each).
  [[nodiscard]] std::size_t readers() const;
  [[nodiscard]] std::vector<ClientInfo> clients() const;
  /// Topics with writers whose type is unknown here (not advertised), "name (type)".
  [[nodiscard]] std::set<std::string> unknown_types() const;

  void OnOpen(const std::shared_ptr<Connection>& connection) override;
  void OnText(const std::shared_ptr<Connection>& connection, std::string_view text) override;
  void OnBinary(const std::shared_ptr<Connection>& connection,
                std::span<const std::byte> data) override;
  void OnClose(const std::shared_ptr<Connection>& connection) override;

 private:
  /// A topic with writers, advertised when its type is known.
  struct TopicState {
    std::string dds_name;
    const dds::MessageTypeInfo* type = nullptr;
    std::map<std::string, OfferedQos> writers;  ///< by writer GUID
    Channel channel;
  };
  /// A topic read for its subscribers. The reader is the last member: it is deleted first,
  /// after its listener has returned.
  struct Reader {
    std::uint32_t channel_id = 0;
    /// (client, subscription id); guarded by the view's mutex.
    std::vector<std::pair<std::shared_ptr<Connection>, std::uint32_t>> subscribers;
    std::mutex take_mutex;  // one taker at a time
    std::unique_ptr<dds::RawReader> reader;
  };
  struct Client {
    std::shared_ptr<Connection> connection;
    std::map<std::uint32_t, std::uint32_t> subscriptions;  ///< subscription id -> channel id
  };

  void Subscribe(const std::shared_ptr<Connection>& connection, const live::Subscribe& request);
  void Unsubscribe(const std::shared_ptr<Connection>& connection,
                   const std::vector<std::uint32_t>& ids);
  // Removes one subscription; moves the channel's reader into `retired` when it was the last.
  // Caller holds mutex_.
  void RemoveSubscription(Client& client, std::uint32_t subscription_id,
                          std::vector<std::unique_ptr<Reader>>& retired);
  // Deletes readers; the caller holds lifecycle_mutex_, not mutex_ (their listeners take it).
  static void Retire(std::vector<std::unique_ptr<Reader>>& retired);
  void Forward(Reader& reader);
  void Broadcast(const std::string& json);  // caller holds mutex_

  const dds::Participant& participant_;
  LiveOptions options_;
  std::string session_id_;
  dds::PublicationWatcher publications_;  // Discover's thread only

  // Serialises making and deleting readers (the I/O thread's subscriptions, Discover's
  // unadvertising, the destructor): a reader is deleted, waiting for its listener, while this is
  // held and mutex_ is not. Listeners never take it. Taken before mutex_.
  std::mutex lifecycle_mutex_;
  mutable std::mutex mutex_;                          // guards everything below
  std::map<std::string, TopicState> topics_;          // by DDS name
  std::map<std::string, std::uint32_t> channel_ids_;  // "name type" -> id, kept when gone
  std::map<std::uint32_t, std::string> advertised_;   // channel id -> DDS name
  std::set<std::string> unknown_types_;
  std::map<std::uint32_t, std::unique_ptr<Reader>> readers_;  // by channel id
  std::map<const Connection*, Client> clients_;
};

}  // namespace autodrive::ros2::live
