#include "ros2/live/live_view.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "ros2/record/ros2msg_schema.h"

#include "common/dds/topics.h"
#include "common/error.h"
#include "common/time.h"

namespace autodrive::ros2::live {

namespace {

std::string KeyText(const std::array<std::uint8_t, 16>& key) {
  return std::string(key.begin(), key.end());
}

std::uint64_t ReceiveTimeNs() {
  return static_cast<std::uint64_t>(
      std::max<std::int64_t>(0, SystemNow().time_since_epoch().count()));
}

template <typename... Handlers>
struct Overload : Handlers... {
  using Handlers::operator()...;
};

}  // namespace

LiveView::LiveView(const dds::Participant& participant, LiveOptions options)
    : participant_(participant),
      options_(std::move(options)),
      session_id_(std::to_string(ReceiveTimeNs())),
      publications_(participant) {}

LiveView::~LiveView() {
  std::lock_guard lifecycle(lifecycle_mutex_);
  std::vector<std::unique_ptr<Reader>> retired;
  {
    std::lock_guard lock(mutex_);
    for (auto& [id, reader] : readers_) retired.push_back(std::move(reader));
    readers_.clear();
  }
  Retire(retired);
}

void LiveView::Discover() {
  const std::vector<dds::WriterChange> changes = publications_.TakeChanges();
  if (changes.empty()) return;
  std::lock_guard lifecycle(lifecycle_mutex_);
  std::vector<std::unique_ptr<Reader>> retired;
  {
    std::lock_guard lock(mutex_);
    std::set<std::string> changed;
    for (const dds::WriterChange& change : changes) {
      const dds::DiscoveredWriter& w = change.writer;
      if (!w.topic_name.starts_with("rt/")) continue;  // not a ROS topic (ros_discovery_info)
      TopicState& topic = topics_[w.topic_name];
      topic.dds_name = w.topic_name;
      if (change.alive) {
        topic.writers[KeyText(w.key)] = OfferedQosOf(w.qos.get());
        if (topic.type == nullptr) topic.type = dds::FindMessageType(w.type_name);
        if (topic.type == nullptr) {
          if (unknown_types_.insert(w.topic_name + " (" + w.type_name + ")").second) {
            spdlog::warn("autodrive-live: {} has type {}, unknown here: not advertised",
                         w.topic_name, w.type_name);
          }
        }
      } else {
        topic.writers.erase(KeyText(w.key));
      }
      changed.insert(w.topic_name);
    }
    std::vector<Channel> appeared;
    std::vector<std::uint32_t> gone;
    for (const std::string& name : changed) {
      TopicState& topic = topics_.at(name);
      const bool advertised = topic.channel.id != 0 && advertised_.contains(topic.channel.id);
      if (!topic.writers.empty() && !advertised && topic.type != nullptr) {
        std::string ros_name;
        try {
          ros_name = dds::topics::ToRos(name);
        } catch (const InputError&) {
          continue;
        }
        const std::string& type_name = topic.type->ros_type_name;
        auto id = channel_ids_.find(ros_name + " " + type_name);
        if (id == channel_ids_.end()) {
          id = channel_ids_
                   .emplace(ros_name + " " + type_name,
                            static_cast<std::uint32_t>(channel_ids_.size() + 1))
                   .first;
        }
        topic.channel.id = id->second;
        topic.channel.topic = ros_name;
        topic.channel.schema_name = type_name;
        topic.channel.schema = std::string(Ros2MsgSchema(type_name));
        advertised_[topic.channel.id] = name;
        appeared.push_back(topic.channel);
        spdlog::info("autodrive-live: advertising {} ({}) as channel {}", ros_name, type_name,
                     topic.channel.id);
      } else if (topic.writers.empty() && advertised) {
        const std::uint32_t id = topic.channel.id;
        advertised_.erase(id);
        gone.push_back(id);
        spdlog::info("autodrive-live: {} has no writer left: unadvertised", topic.channel.topic);
        // Its subscriptions end (a client subscribes again when it is advertised again).
        for (auto& [key, client] : clients_) {
          std::vector<std::uint32_t> ended;
          for (const auto& [sub, channel] : client.subscriptions) {
            if (channel == id) ended.push_back(sub);
          }
          for (std::uint32_t sub : ended) RemoveSubscription(client, sub, retired);
        }
      }
    }
    if (!appeared.empty()) Broadcast(AdvertiseJson(appeared));
    if (!gone.empty()) Broadcast(UnadvertiseJson(gone));
  }
  Retire(retired);
}

std::vector<Channel> LiveView::channels() const {
  std::lock_guard lock(mutex_);
  std::vector<Channel> out;
  for (const auto& [id, name] : advertised_) out.push_back(topics_.at(name).channel);
  return out;
}

std::size_t LiveView::readers() const {
  std::lock_guard lock(mutex_);
  return readers_.size();
}

std::vector<ClientInfo> LiveView::clients() const {
  std::lock_guard lock(mutex_);
  std::vector<ClientInfo> out;
  for (const auto& [key, client] : clients_) {
    out.push_back({client.connection->id(), client.connection->remote(),
                   client.subscriptions.size(), client.connection->stats()});
  }
  return out;
}

std::set<std::string> LiveView::unknown_types() const {
  std::lock_guard lock(mutex_);
  return unknown_types_;
}

void LiveView::OnOpen(const std::shared_ptr<Connection>& connection) {
  std::lock_guard lock(mutex_);
  clients_[connection.get()].connection = connection;
  connection->Send(
      OutFrame::Text(ServerInfoJson(options_.server_name, options_.metadata, session_id_)));
  std::vector<Channel> all;
  for (const auto& [id, name] : advertised_) all.push_back(topics_.at(name).channel);
  connection->Send(OutFrame::Text(AdvertiseJson(all)));
  spdlog::info("autodrive-live: client {} ({}, {}) connected", connection->id(),
               connection->remote(), connection->subprotocol());
}

void LiveView::OnText(const std::shared_ptr<Connection>& connection, std::string_view text) {
  const ClientMessage message = ParseClientText(text);
  std::visit(Overload{
                 [&](const live::Subscribe& s) { Subscribe(connection, s); },
                 [&](const live::Unsubscribe& u) { Unsubscribe(connection, u.subscription_ids); },
                 [&](const Unsupported& u) {
                   connection->Send(OutFrame::Text(StatusJson(
                       StatusLevel::kError, "autodrive-live is read-only: '" + u.op +
                                                "' is not supported (no capability announced)")));
                 },
                 [&](const UnknownOp& u) {
                   connection->Send(OutFrame::Text(
                       StatusJson(StatusLevel::kWarning, "unknown op '" + u.op + "'")));
                 },
                 [&](const Malformed& m) {
                   connection->Send(OutFrame::Text(
                       StatusJson(StatusLevel::kError, "malformed message: " + m.why)));
                 },
             },
             message);
}

void LiveView::OnBinary(const std::shared_ptr<Connection>& connection,
                        std::span<const std::byte> data) {
  const ClientMessage message = ParseClientBinary(data);
  if (const auto* u = std::get_if<Unsupported>(&message)) {
    connection->Send(OutFrame::Text(StatusJson(
        StatusLevel::kError,
        "autodrive-live is read-only: " + u->op + " is not supported (no capability announced)")));
  } else if (const auto* op = std::get_if<UnknownOp>(&message)) {
    connection->Send(
        OutFrame::Text(StatusJson(StatusLevel::kWarning, "unknown " + op->op + " ignored")));
  } else if (const auto* m = std::get_if<Malformed>(&message)) {
    connection->Send(
        OutFrame::Text(StatusJson(StatusLevel::kError, "malformed message: " + m->why)));
  }
}

void LiveView::OnClose(const std::shared_ptr<Connection>& connection) {
  std::lock_guard lifecycle(lifecycle_mutex_);
  std::vector<std::unique_ptr<Reader>> retired;
  {
    std::lock_guard lock(mutex_);
    const auto it = clients_.find(connection.get());
    if (it == clients_.end()) return;
    std::vector<std::uint32_t> subs;
    for (const auto& [sub, channel] : it->second.subscriptions) subs.push_back(sub);
    for (std::uint32_t sub : subs) RemoveSubscription(it->second, sub, retired);
    const ConnectionStats stats = connection->stats();
    spdlog::info("autodrive-live: client {} ({}) disconnected: {} frames sent, {} dropped",
                 connection->id(), connection->remote(), stats.sent_frames, stats.dropped_frames);
    clients_.erase(it);
  }
  Retire(retired);
}

void LiveView::Subscribe(const std::shared_ptr<Connection>& connection,
                         const live::Subscribe& request) {
  // Readers are made without mutex_: making one takes Cyclone's locks, which a listener holds
  // when it takes mutex_ (Forward), so holding mutex_ here could deadlock (ThreadSanitizer's
  // lock-order report). lifecycle_mutex_, which no listener takes, keeps the rest out meanwhile.
  std::lock_guard lifecycle(lifecycle_mutex_);
  struct Wanted {
    std::uint32_t sub = 0;
    std::uint32_t channel = 0;
    std::unique_ptr<Reader> made;  // a new reader, when the channel has none yet
  };
  std::vector<Wanted> wanted;
  std::vector<std::pair<std::string, const TopicState*>> to_make;  // by index into wanted
  {
    std::lock_guard lock(mutex_);
    Client& client = clients_[connection.get()];
    for (const auto& [sub, channel] : request.subscriptions) {
      std::string refusal;
      const auto advertised = advertised_.find(channel);
      const auto taken = [&](std::uint32_t c, std::uint32_t s) {
        return std::any_of(client.subscriptions.begin(), client.subscriptions.end(),
                           [&](const auto& e) { return c ? e.second == c : e.first == s; }) ||
               std::any_of(wanted.begin(), wanted.end(),
                           [&](const Wanted& w) { return c ? w.channel == c : w.sub == s; });
      };
      if (taken(0, sub)) {
        refusal = "subscription id " + std::to_string(sub) + " is in use";
      } else if (advertised == advertised_.end()) {
        refusal = "channel " + std::to_string(channel) + " is not advertised";
      } else if (taken(channel, 0)) {
        refusal = "channel " + std::to_string(channel) + " is subscribed already";
      }
      if (!refusal.empty()) {
        connection->Send(OutFrame::Text(StatusJson(StatusLevel::kError, "subscribe: " + refusal)));
        continue;
      }
      wanted.push_back({sub, channel, nullptr});
      to_make.emplace_back(readers_.contains(channel) ? std::string() : advertised->second,
                           &topics_.at(advertised->second));
    }
  }
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    if (to_make[i].first.empty()) continue;
    const TopicState& topic = *to_make[i].second;  // topics_ changes only under lifecycle_mutex_
    std::vector<OfferedQos> offered;
    for (const auto& [key, qos] : topic.writers) offered.push_back(qos);
    auto made = std::make_unique<Reader>();
    made->channel_id = wanted[i].channel;
    try {
      made->reader =
          std::make_unique<dds::RawReader>(participant_, topic.dds_name, topic.type->descriptor,
                                           ReaderQos(offered, options_.reader_depth));
      wanted[i].made = std::move(made);
    } catch (const std::exception& e) {
      wanted[i].channel = 0;  // not subscribed
      connection->Send(OutFrame::Text(StatusJson(
          StatusLevel::kError, "subscribe: cannot read " + topic.channel.topic + ": " + e.what())));
    }
  }
  std::vector<Reader*> started;
  {
    std::lock_guard lock(mutex_);
    Client& client = clients_[connection.get()];
    for (Wanted& w : wanted) {
      if (w.channel == 0) continue;
      auto& reader = readers_[w.channel];
      if (w.made) {
        reader = std::move(w.made);
        started.push_back(reader.get());
        spdlog::info("autodrive-live: reading {}",
                     topics_.at(advertised_.at(w.channel)).channel.topic);
      }
      if (!reader) {  // cannot happen: readers_ changes only under lifecycle_mutex_
        readers_.erase(w.channel);
        continue;
      }
      reader->subscribers.emplace_back(connection, w.sub);
      client.subscriptions[w.sub] = w.channel;
    }
  }
  // Outside mutex_: the listener takes it (and runs at once for what is waiting). The readers
  // started here are alive: only a holder of lifecycle_mutex_ deletes one.
  for (Reader* r : started) {
    r->reader->OnDataAvailable([this, r] { Forward(*r); });
  }
}

void LiveView::Unsubscribe(const std::shared_ptr<Connection>& connection,
                           const std::vector<std::uint32_t>& ids) {
  std::lock_guard lifecycle(lifecycle_mutex_);
  std::vector<std::unique_ptr<Reader>> retired;
  {
    std::lock_guard lock(mutex_);
    Client& client = clients_[connection.get()];
    for (std::uint32_t sub : ids) {
      if (!client.subscriptions.contains(sub)) {
        connection->Send(OutFrame::Text(StatusJson(
            StatusLevel::kWarning, "unsubscribe: no subscription with id " + std::to_string(sub))));
        continue;
      }
      RemoveSubscription(client, sub, retired);
    }
  }
  Retire(retired);
}

void LiveView::RemoveSubscription(Client& client, std::uint32_t subscription_id,
                                  std::vector<std::unique_ptr<Reader>>& retired) {
  const auto sub = client.subscriptions.find(subscription_id);
  if (sub == client.subscriptions.end()) return;
  const std::uint32_t channel = sub->second;
  client.subscriptions.erase(sub);
  const auto reader = readers_.find(channel);
  if (reader == readers_.end()) return;
  auto& subscribers = reader->second->subscribers;
  std::erase_if(subscribers, [&](const auto& s) {
    return s.first == client.connection && s.second == subscription_id;
  });
  if (subscribers.empty()) {
    retired.push_back(std::move(reader->second));
    readers_.erase(reader);
  }
}

void LiveView::Retire(std::vector<std::unique_ptr<Reader>>& retired) {
  for (auto& r : retired) {
    r->reader->OnDataAvailable({});  // waits for a running listener
    r.reset();
  }
  retired.clear();
}

void LiveView::Forward(Reader& reader) {
  struct Taken {
    std::uint64_t receive_ns = 0;
    std::shared_ptr<const std::vector<std::byte>> payload;
  };
  std::vector<Taken> taken;
  {
    std::lock_guard lock(reader.take_mutex);
    dds::RawSample sample;
    while (reader.reader->Take(sample)) {
      taken.push_back(
          {ReceiveTimeNs(), std::make_shared<const std::vector<std::byte>>(std::move(sample.cdr))});
      sample.cdr = {};
    }
  }
  if (taken.empty()) return;
  // Under the lock, so that an unsubscribed client gets nothing more; Send only queues.
  std::lock_guard lock(mutex_);
  for (const auto& [connection, sub] : reader.subscribers) {
    for (const Taken& t : taken) {
      connection->Send(OutFrame::Data(EncodeMessageDataHeader(sub, t.receive_ns), t.payload));
    }
  }
}

void LiveView::Broadcast(const std::string& json) {
  for (auto& [key, client] : clients_) client.connection->Send(OutFrame::Text(json));
}

}  // namespace autodrive::ros2::live
