#include "scm/io/inbox.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <string_view>
#include <utility>

#include "common/dds/topics.h"
#include "common/error.h"

namespace autodrive::scm {

namespace {

constexpr std::string_view kOperatorTopicPrefix = "rt/autodrive/scm/operator/";
constexpr std::string_view kOperatorTopicSuffix = "/request";

}  // namespace

ScmInbox::ScmInbox(dds::Participant& participant, const Clock& clock, dds::LoopWaitSet& waitset)
    : participant_(participant), waitset_(waitset) {
  signal_requests_ =
      std::make_unique<dds::Reader<msg::SignalRequest>>(participant, dds::topics::SignalRequests());
  device_statuses_ = std::make_unique<DeviceStatusInbox>(participant, clock);
  processes_ = std::make_unique<ProcessTableInbox>(participant);
  waitset_.Attach(*signal_requests_);
  publications_ = std::make_unique<dds::PublicationWatcher>(participant);
}

ScmInbox::~ScmInbox() = default;

void ScmInbox::AddOperator(std::string name) {
  auto reader = std::make_unique<dds::Reader<msg::OperatorRequest>>(
      participant_, dds::topics::OperatorRequests(name));
  operators_.push_back(OperatorTopic{std::move(name), std::move(reader)});
}

void ScmInbox::OpenOperators(const std::vector<std::string>& operators) {
  operators_.clear();
  strangers_ = 0;
  operators_.push_back(OperatorTopic{"", std::make_unique<dds::Reader<msg::OperatorRequest>>(
                                             participant_, dds::topics::OperatorRequests())});
  for (const auto& name : operators) AddOperator(name);
  for (const auto& topic : operators_) waitset_.Attach(*topic.reader);
}

void ScmInbox::WatchStrangers() {
  // An operator the city does not allow still gets an answer (a refusal): read the operator
  // topics that writers appear on, up to a bound.
  for (const std::string& topic : publications_->TakeTopics()) {
    // The shared topic (".../operator/request") has the prefix and the suffix overlapping:
    // only a topic longer than both names an operator.
    if (topic.size() <= kOperatorTopicPrefix.size() + kOperatorTopicSuffix.size() ||
        !topic.starts_with(kOperatorTopicPrefix) || !topic.ends_with(kOperatorTopicSuffix)) {
      continue;
    }
    const std::string name =
        topic.substr(kOperatorTopicPrefix.size(),
                     topic.size() - kOperatorTopicPrefix.size() - kOperatorTopicSuffix.size());
    if (std::ranges::any_of(operators_, [&](const auto& t) { return t.operator_name == name; })) {
      continue;
    }
    if (strangers_ >= kMaxStrangerOperators) continue;
    try {
      AddOperator(name);
      waitset_.Attach(*operators_.back().reader);
      ++strangers_;
      spdlog::warn(
          "a writer appeared for operator '{}', whom the city does not allow; its "
          "requests will be refused",
          name);
    } catch (const InputError&) {
      // Not an operator name we could ever allow: nothing to answer.
    }
  }
}

std::optional<ScmInbox::OperatorRequestIn> ScmInbox::TakeOperatorRequest() {
  for (; operator_cursor_ < operators_.size(); ++operator_cursor_) {
    const OperatorTopic& topic = operators_[operator_cursor_];
    if (topic.reader->TakeOne(request_sample_, &request_info_)) {
      return OperatorRequestIn{
          *request_sample_, topic.operator_name,
          requesters_.Find(topic.reader->handle(), request_info_.publication_handle)};
    }
  }
  return std::nullopt;
}

const msg::SignalRequest* ScmInbox::TakeSignalRequest() {
  return signal_requests_->TakeOne(signal_sample_) ? &*signal_sample_ : nullptr;
}

bool ScmInbox::RequestWaiting() const {
  if (signal_requests_->HasSamples()) return true;
  return std::any_of(operators_.begin(), operators_.end(),
                     [](const OperatorTopic& t) { return t.reader->HasSamples(); });
}

std::span<const ReceivedReport> ScmInbox::TakeDeviceReports() {
  const std::size_t n = device_statuses_->Drain(reports_);
  return {reports_.data(), n};
}

std::uint64_t ScmInbox::TakeDeviceRefusals() {
  const std::uint64_t refused = device_statuses_->malformed() + device_statuses_->dropped();
  const std::uint64_t fresh = refused - device_refusals_seen_;
  device_refusals_seen_ = refused;
  return fresh;
}

}  // namespace autodrive::scm
