#include "infrastructure/serial_backend.h"

#include <spdlog/spdlog.h>

#include <cstdio>
#include <utility>

#include "infrastructure/internal/overloaded.h"

namespace autodrive::infrastructure {
namespace {

std::string Seconds(std::chrono::milliseconds ms) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f s", static_cast<double>(ms.count()) / 1000.0);
  return text;
}

}  // namespace

SerialBackend::SerialBackend(SerialBackendOptions options) : options_(std::move(options)) {
  TryOpen(std::chrono::steady_clock::now());
}

std::string SerialBackend::Describe() const {
  return "serial " + options_.port + " at " + std::to_string(options_.baud) + " baud";
}

void SerialBackend::Show(Aspect aspect, const Lamps& /*lamps: the MCU flashes by itself*/) {
  desired_ = aspect;
  if (port_) SendSetIfNeeded(std::chrono::steady_clock::now());
}

LampFeedback SerialBackend::Poll() {
  const SteadyTime now = std::chrono::steady_clock::now();
  if (!port_ && now >= next_attempt_) TryOpen(now);
  if (port_) {
    read_buffer_.clear();
    const bool ok = port_->ReadAvailable(read_buffer_);
    const std::string error = ok ? std::string() : port_->error();
    lines_.Append(read_buffer_);
    while (auto line = lines_.Next()) Handle(*line, now);  // may close the port
    if (!ok && port_) Close("port " + options_.port + " closed (" + error + ")", now);
  }
  if (port_) {
    SendSetIfNeeded(now);
    if (port_ && now - last_write_ >= options_.keepalive) Send(serial::Ping{}, now);
  }
  for (auto it = faults_.begin(); it != faults_.end();) {
    it = now - it->second.last_seen > options_.fault_expiry ? faults_.erase(it) : std::next(it);
  }

  LampFeedback feedback;
  if (!port_) {
    feedback.online = false;
    feedback.offline_reason = port_problem_;
  } else if (!last_line_ || now - *last_line_ > options_.answer_timeout) {
    const SteadyTime since = last_line_ ? *last_line_ : *opened_at_;
    if (now - since > options_.answer_timeout) {
      feedback.online = false;
      feedback.offline_reason = "no answer from the lamp controller on " + options_.port + " for " +
                                Seconds(options_.answer_timeout);
    } else {
      feedback.online = false;
      feedback.offline_reason = "waiting for the lamp controller on " + options_.port;
    }
  }
  if (feedback.online) {
    feedback.lamps = lamps_;
    for (const auto& [lamp, fault] : faults_) feedback.faults.push_back({lamp, fault.reason});
  }
  return feedback;
}

void SerialBackend::TryOpen(SteadyTime now) {
  next_attempt_ = now + options_.reconnect_interval;
  try {
    port_.emplace(options_.port, options_.baud);
  } catch (const InputError& e) {
    if (port_problem_ != e.what()) spdlog::warn("{}: {}", Describe(), e.what());
    port_problem_ = e.what();
    return;
  }
  ++connects_;
  spdlog::info("{}: port open", Describe());
  lines_.Clear();
  opened_at_ = now;
  last_line_.reset();
  faults_.clear();
  lamps_ = Lamps{};
  sent_.reset();
  acked_.reset();
  Send(serial::Flash{static_cast<int>(
           std::chrono::duration_cast<std::chrono::milliseconds>(options_.flash_period).count())},
       now);
  if (port_) SendSetIfNeeded(now);
}

void SerialBackend::Close(const std::string& reason, SteadyTime now) {
  spdlog::warn("{}: {}", Describe(), reason);
  port_.reset();
  port_problem_ = reason;
  next_attempt_ = now + options_.reconnect_interval;
  last_line_.reset();
}

void SerialBackend::Send(const serial::HostCommand& command, SteadyTime now) {
  if (!port_) return;
  const std::string line = serial::Format(command) + "\n";
  if (!port_->Write(line)) {
    Close("cannot write to " + options_.port + " (" + port_->error() + ")", now);
    return;
  }
  last_write_ = now;
}

void SerialBackend::SendSetIfNeeded(SteadyTime now) {
  if (!desired_) return;
  const bool changed = sent_ != desired_;
  const bool unacked = acked_ != desired_ && now - sent_at_ > options_.ack_timeout;
  if (!changed && !unacked) return;
  sent_ = desired_;
  sent_at_ = now;
  Send(serial::Set{*desired_}, now);
}

void SerialBackend::Handle(const std::string& line, SteadyTime now) {
  serial::McuReport report;
  try {
    report = serial::ParseMcuReport(line);
  } catch (const serial::ProtocolError& e) {
    ++bad_lines_;
    spdlog::debug("{}: ignored a line that does not follow {}: {}", Describe(), serial::kProtocol,
                  e.what());
    return;
  }
  last_line_ = now;
  std::visit(
      internal::Overloaded{
          [&](const serial::Hello& h) {
            // The MCU restarted: it forgot the flash period and the aspect.
            spdlog::info("{}: lamp controller says hello ({})", Describe(), h.protocol);
            if (h.protocol != serial::kProtocol) {
              spdlog::warn("{}: controller speaks {}, we speak {}", Describe(), h.protocol,
                           serial::kProtocol);
            }
            faults_.clear();
            sent_.reset();
            acked_.reset();
            Send(serial::Flash{static_cast<int>(
                     std::chrono::duration_cast<std::chrono::milliseconds>(options_.flash_period)
                         .count())},
                 now);
            SendSetIfNeeded(now);
          },
          [&](const serial::Ok& ok) {
            if (ok.command.starts_with("SET ")) {
              acked_ = serial::AspectFromName(std::string_view(ok.command).substr(4));
            }
          },
          [&](const serial::Err& err) {
            ++errors_;
            spdlog::warn("{}: controller refused a command: {} {}", Describe(), err.code, err.text);
          },
          [&](const serial::LampsReport& r) { lamps_ = r.lamps; },
          [&](const serial::Fault& f) {
            faults_[f.lamp] = ActiveFault{f.reason, now};
          },
          [&](const serial::Clear& c) { faults_.erase(c.lamp); },
          [&](const serial::Watchdog&) {
            spdlog::warn("{}: the controller's watchdog tripped (it flashes red)", Describe());
            acked_.reset();
            sent_.reset();
          },
      },
      report);
}

}  // namespace autodrive::infrastructure
