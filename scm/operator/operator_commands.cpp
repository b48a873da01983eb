#include "scm/operator/operator_commands.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>

#include "common/error.h"
#include "scm/io/map_data.h"

namespace autodrive::scm {

namespace {

using Handler = std::optional<Reply> (*)(const OperatorCommand&, const ClockReading&,
                                         CommandContext&, Responder&);

std::optional<std::size_t> Intersection(const OperatorCommand& cmd, const CommandContext& ctx,
                                        Reply& error) {
  if (const auto x = ctx.runtime.Find(cmd.intersection)) return x;
  std::string names;
  for (const auto& r : ctx.runtime.intersections()) {
    names += (names.empty() ? "" : ", ") + r.model->name;
  }
  error = Reply::Invalid(
      fmt::format("unknown intersection \"{}\" (signalised: {})", cmd.intersection, names));
  return std::nullopt;
}

std::optional<Reply> Status(const OperatorCommand&, const ClockReading& now, CommandContext& ctx,
                            Responder&) {
  const City& city = ctx.runtime.city();
  const double uptime = ToSeconds(now.mono - ctx.figures.started);
  const auto db = ctx.persistence.stats();
  const auto& cp = ctx.control.counters();
  Reply r = Reply::Ok(fmt::format("city {}: {} signalised intersections, {} lights, up {:.0f} s",
                                  city.config.name, ctx.runtime.intersections().size(),
                                  ctx.runtime.heads().size(), uptime));
  auto add = [&](std::string k, std::string v) {
    r.values.emplace_back(std::move(k), std::move(v));
  };
  add("city", city.config.name);
  add("config", ctx.figures.config_path);
  add("clock", ToString(ctx.figures.clock));
  add("uptime_s", fmt::format("{:.1f}", uptime));
  add("lights", std::to_string(ctx.runtime.heads().size()));
  add("lights_lost", std::to_string(ctx.supervisor.lost()));
  add("events", std::to_string(db.event_count));
  add("events_dropped", std::to_string(db.events_dropped));
  add("database_bytes", std::to_string(db.size_bytes));
  add("spat_published", std::to_string(ctx.publishers.counters().spat));
  add("write_failures",
      std::to_string(ctx.publishers.counters().write_failures + ctx.lights.counters().failures));
  add("light_commands", std::to_string(ctx.lights.counters().writes));
  add("light_resends", std::to_string(ctx.lights.counters().resends));
  add("requests", std::to_string(cp.received));
  add("refused_invalid", std::to_string(cp.invalid));
  add("refused_rate", std::to_string(cp.rate_limited));
  add("refused_not_allowed", std::to_string(cp.not_allowed));
  add("malformed_requests", std::to_string(cp.invalid + ctx.figures.malformed_inputs));
  add("foreign_devices", std::to_string(ctx.supervisor.counters().foreign_city +
                                        ctx.supervisor.counters().foreign_host));
  add("signal_requests", std::to_string(ctx.figures.signal_requests));
  add("background_vehicles", std::to_string(ctx.fleet.BackgroundVehicles(now.wire)));
  add("monitor_violations", std::to_string(ctx.figures.monitor_violations));
  add("stalls", std::to_string(ctx.figures.stalls));
  add("longest_stall_ms", fmt::format("{:.0f}", ToSeconds(ctx.figures.longest_stall) * 1000.0));
  add("reused_request_ids", std::to_string(cp.reused_ids));
  const ReplyCounters& rc = ctx.figures.replies;
  add("replies_sent", std::to_string(rc.sent));
  add("replies_waited_for_reader", std::to_string(rc.waited_for_match));
  add("replies_waited_for_writer", std::to_string(rc.waited_for_writer));
  add("replies_unmatched", std::to_string(rc.unmatched));
  add("replies_dropped", std::to_string(rc.dropped));
  add("reply_write_refusals", std::to_string(ctx.figures.reply_write_refusals));
  return r;
}

std::optional<Reply> Intersections(const OperatorCommand&, const ClockReading&, CommandContext& ctx,
                                   Responder&) {
  Reply r =
      Reply::Ok(fmt::format("{} signalised intersections", ctx.runtime.intersections().size()));
  for (std::size_t i = 0; i < ctx.runtime.intersections().size(); ++i) {
    r.values.emplace_back(ctx.runtime.intersections()[i].model->name, ctx.runtime.Describe(i));
  }
  return r;
}

std::optional<Reply> Show(const OperatorCommand& cmd, const ClockReading& now, CommandContext& ctx,
                          Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  const IntersectionRuntime& x = ctx.runtime.intersections()[*xi];
  Reply r = Reply::Ok(x.model->name + ": " + ctx.runtime.Describe(*xi));
  const auto signals = x.controller->Signals(now.mono);
  for (std::size_t g = 0; g < signals.size(); ++g) {
    const auto& s = signals[g];
    std::string heads;
    for (const SignalHeadId h : x.model->groups[g].heads) {
      const auto hi = ctx.runtime.HeadIndex(h);
      if (!hi) continue;
      const HeadHealth& health = ctx.supervisor.head(*hi);
      heads += fmt::format(" {}={}{}", ctx.runtime.heads()[*hi].name,
                           health.displayed ? ToString(*health.displayed) : "unseen",
                           health.lost ? "(lost)" : "");
    }
    r.values.emplace_back(
        fmt::format("group {} {}", x.model->groups[g].id.value(), x.model->groups[g].name),
        fmt::format("{} since {:.1f} s, min end in {:.1f} s{};{}", ToString(s.aspect),
                    ToSeconds(now.mono - s.since), ToSeconds(s.min_end - now.mono),
                    s.likely_end
                        ? fmt::format(", likely in {:.1f} s", ToSeconds(*s.likely_end - now.mono))
                        : "",
                    heads));
  }
  // Vehicles on each approach (its ingress lanes and the box's movements from it).
  const maps::Intersection& mx = ctx.runtime.city().map.intersection(x.model->id);
  for (const ApproachCount& a : ctx.fleet.ApproachCounts(x.model->id, now.wire)) {
    const auto it = std::ranges::find(mx.approaches, a.approach, &maps::Approach::id);
    r.values.emplace_back(fmt::format("approach {}", ApproachName(it->side)),
                          fmt::format("{} lab, {} background vehicles", a.lab, a.background));
  }
  if (ctx.supervisor.monitor_seen(*xi)) {
    r.values.emplace_back("infrastructure monitor",
                          ctx.supervisor.monitor_latched(*xi) ? "latched" : "watching");
  }
  return r;
}

/// The end of every state-changing command on one intersection: log, persist, step.
Reply Changed(const OperatorCommand& cmd, std::size_t xi, const CommandResult& res,
              const ClockReading& now, CommandContext& ctx) {
  IntersectionRuntime& x = ctx.runtime.intersections()[xi];
  if (!res.ok) return Reply::Rejected(res.message);
  ctx.events.Emit(Event{Severity::kInfo, "operator_" + cmd.name,
                        fmt::format("{} {}: {}", cmd.name, x.model->name, res.message), x.model->id,
                        "", cmd.actor, false});
  if (auto state = ctx.runtime.TakeStateToSave(xi, now.wire)) {
    ctx.persistence.SaveIntersectionState(std::move(*state));
  }
  ctx.runtime.StepOne(xi, now, ctx.day, ctx.events);
  return Reply::Ok(res.message);
}

std::optional<Reply> SetMode(const OperatorCommand& cmd, const ClockReading& now,
                             CommandContext& ctx, Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  const auto mode = ModeFromString(cmd.Arg("mode"));
  if (!mode) {
    return Reply::Invalid(fmt::format(
        "unknown mode \"{}\" (auto, fixed, actuated, manual, flash, dark)", cmd.Arg("mode")));
  }
  auto& c = *ctx.runtime.intersections()[*xi].controller;
  return Changed(cmd, *xi, c.SetMode(*mode, now.mono), now, ctx);
}

std::optional<Reply> SetPlan(const OperatorCommand& cmd, const ClockReading& now,
                             CommandContext& ctx, Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  const std::string& plan = cmd.Arg("plan");
  if (plan.empty()) return Reply::Invalid("plan needs a plan name (or auto)");
  const IntersectionModel& model = *ctx.runtime.intersections()[*xi].model;
  if (plan != "auto" && !model.PlanIndex(plan)) {
    // An argument that names nothing, as an unknown mode or intersection is.
    std::string names;
    for (const auto& p : model.plans) names += (names.empty() ? "" : ", ") + p.name;
    return Reply::Invalid(
        fmt::format("{} has no plan \"{}\" (plans: {}, or auto)", model.name, plan, names));
  }
  auto& c = *ctx.runtime.intersections()[*xi].controller;
  return Changed(cmd, *xi, c.SetPlan(cmd.Arg("plan"), now.mono), now, ctx);
}

std::optional<Reply> Advance(const OperatorCommand& cmd, const ClockReading& now,
                             CommandContext& ctx, Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  auto& c = *ctx.runtime.intersections()[*xi].controller;
  return Changed(cmd, *xi, c.Advance(now.mono), now, ctx);
}

std::optional<Reply> Reset(const OperatorCommand& cmd, const ClockReading& now, CommandContext& ctx,
                           Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  IntersectionRuntime& x = ctx.runtime.intersections()[*xi];
  auto& c = *x.controller;
  if (!c.latched()) {
    return Reply::Rejected(
        fmt::format("{} is not in fail-safe flash; nothing to reset", x.model->name));
  }
  // A reset does not clear a cause that is still there; a refused reset changes nothing,
  // here or in the infrastructure.
  if (auto refusal = ctx.supervisor.ResetRefusal(*xi)) return Reply::Rejected(*refusal);
  const std::string reason = c.latch_reason();
  const CommandResult res = c.Reset(now.mono);
  if (!res.ok) return Reply::Rejected(res.message);
  x.fault.clear();
  // The infrastructure's monitor of this intersection, and only it, is reset too.
  std::optional<std::uint64_t> monitor_command;
  if (ctx.supervisor.monitor_seen(*xi)) {
    monitor_command = ctx.publishers.ResetMonitor(*x.model, cmd.actor, cmd.request_id, now.wire);
  }
  ctx.supervisor.OnReset(*xi, now.mono, monitor_command);
  ctx.events.Emit(Event{
      Severity::kInfo, "failsafe_reset",
      fmt::format("{}: fail-safe flash reset by an operator (was: {}){}", x.model->name, reason,
                  monitor_command ? fmt::format("; infrastructure monitor reset "
                                                "(command {})",
                                                *monitor_command)
                                  : std::string()),
      x.model->id, "", cmd.actor, false});
  return Changed(cmd, *xi, res, now, ctx);
}

std::optional<Reply> Events(const OperatorCommand& cmd, const ClockReading&, CommandContext& ctx,
                            Responder& respond) {
  EventQuery q;
  q.limit = 100;
  if (!cmd.Arg("since").empty()) {
    try {
      q.since = TimeFromSeconds(std::stod(cmd.Arg("since")));
    } catch (const std::exception&) {
      return Reply::Invalid(
          fmt::format("since must be seconds since the epoch, got \"{}\"", cmd.Arg("since")));
    }
  }
  if (!cmd.Arg("limit").empty()) {
    const std::string& text = cmd.Arg("limit");
    std::size_t limit = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), limit);
    if (ec != std::errc() || end != text.data() + text.size() || limit == 0 || limit > 10000) {
      return Reply::Invalid(fmt::format("limit must be a number in 1..10000, got \"{}\"", text));
    }
    q.limit = limit;
  }
  ctx.persistence.QueryEvents(q, [respond = std::move(respond)](std::vector<EventRecord> events,
                                                                std::string error) {
    if (!error.empty()) {
      respond(Reply::Failed("cannot read the event log: " + error));
      return;
    }
    Reply r = Reply::Ok(fmt::format("{} events", events.size()));
    for (const auto& e : events) {
      r.values.emplace_back(
          std::to_string(e.id),
          fmt::format("{:.3f} {} {} {}{}{}", ToSeconds(e.time), ToString(e.severity), e.code,
                      e.message, e.actor.empty() || e.actor == "scm" ? "" : " (by " + e.actor + ")",
                      e.active ? " [active]" : ""));
    }
    respond(std::move(r));
  });
  return std::nullopt;
}

/// The YAML of a configuration request, checked against what the client says it sent: its
/// length and hash are required, because a string on the wire ends at its first NUL byte, so
/// a file with one arrives cut short, and a text cut short can still be a valid city.
std::optional<Reply> CheckConfigText(const OperatorCommand& cmd) {
  const std::string& yaml = cmd.Arg("yaml");
  if (yaml.empty()) return Reply::Invalid(cmd.name + " needs the configuration's text (yaml)");
  if (cmd.Arg("yaml_bytes").empty() || cmd.Arg("yaml_hash").empty()) {
    return Reply::Invalid(fmt::format(
        "{} needs yaml_bytes (the text's length in bytes) and yaml_hash (its FNV-1a 64 hash, 16 "
        "hex digits) beside yaml, so that a text cut on the way is refused rather than applied",
        cmd.name));
  }
  const std::string& text = cmd.Arg("yaml_bytes");
  std::size_t bytes = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), bytes);
  if (ec != std::errc() || end != text.data() + text.size()) {
    return Reply::Invalid(fmt::format("yaml_bytes must be a number, got \"{}\"", text));
  }
  if (bytes != yaml.size()) {
    return Reply::Invalid(fmt::format(
        "the configuration arrived with {} bytes but was sent with {} (a NUL byte cuts a "
        "string on the wire): refused",
        yaml.size(), bytes));
  }
  if (cmd.Arg("yaml_hash") != ContentHash(yaml)) {
    return Reply::Invalid(fmt::format("the configuration's hash is {}, not the {} it was sent with",
                                      ContentHash(yaml), cmd.Arg("yaml_hash")));
  }
  return std::nullopt;
}

std::optional<Reply> ConfigValidate(const OperatorCommand& cmd, const ClockReading&,
                                    CommandContext& ctx, Responder& respond) {
  if (auto bad = CheckConfigText(cmd)) return bad;
  const std::string label = cmd.Arg("path").empty() ? "<operator>" : cmd.Arg("path");
  ctx.config.Validate(cmd.Arg("yaml"), label, std::move(respond));
  return std::nullopt;
}

std::optional<Reply> ConfigApply(const OperatorCommand& cmd, const ClockReading&,
                                 CommandContext& ctx, Responder& respond) {
  if (auto bad = CheckConfigText(cmd)) return bad;
  const std::string label = cmd.Arg("path").empty() ? "<operator>" : cmd.Arg("path");
  ctx.config.Apply(cmd.Arg("yaml"), label, cmd.actor, std::move(respond));
  return std::nullopt;
}

struct Entry {
  std::string_view name;
  Handler handler;
};
constexpr Entry kHandlers[] = {
    {"status", Status},
    {"intersections", Intersections},
    {"show", Show},
    {"events", Events},
    {"config_validate", ConfigValidate},
    {"mode", SetMode},
    {"plan", SetPlan},
    {"advance", Advance},
    {"reset", Reset},
    {"config_apply", ConfigApply},
};

}  // namespace

std::optional<Reply> RunOperatorCommand(const OperatorCommand& command, const ClockReading& now,
                                        CommandContext& context, Responder respond) {
  for (const auto& e : kHandlers) {
    if (e.name != command.name) continue;
    try {
      return e.handler(command, now, context, respond);
    } catch (const std::exception& ex) {
      // A bug, or a database that cannot be read: the daemon answers and carries on.
      spdlog::error("operator command {} failed: {}", command.name, ex.what());
      return Reply::Failed(ex.what());
    }
  }
  return Reply::Invalid(
      fmt::format("unknown command \"{}\" ({})", command.name, OperatorCommandNames()));
}

}  // namespace autodrive::scm
