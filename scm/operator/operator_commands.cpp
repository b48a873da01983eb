#include "scm/operator/operator_commands.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iterator>
#include <ranges>

#include "common/error.h"
#include "scm/core/intergreen.h"
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

/// Seconds of `d`, to the millisecond.
double Ms(Duration d) { return std::round(ToSeconds(d) * 1000.0) / 1000.0; }

/// A group of `show`: its aspect and times (seconds from now), its lights and what each shows.
nlohmann::json GroupJson(const SignalGroup& group, const GroupSignal& s, MonoTime now,
                         const CommandContext& ctx) {
  nlohmann::json heads = nlohmann::json::array();
  std::string heads_text;
  for (const SignalHeadId h : group.heads) {
    const auto hi = ctx.runtime.HeadIndex(h);
    if (!hi) continue;
    const HeadHealth& health = ctx.supervisor.head(*hi);
    const std::string& name = ctx.runtime.heads()[*hi].name;
    heads.push_back({{"head", name},
                     {"displayed", health.displayed ? nlohmann::json(ToString(*health.displayed))
                                                    : nlohmann::json()},
                     {"lost", health.lost}});
    heads_text +=
        fmt::format(" {}={}{}", name, health.displayed ? ToString(*health.displayed) : "unseen",
                    health.lost ? "(lost)" : "");
  }
  std::string text = fmt::format(
      "{} since {:.1f} s, min end in {:.1f} s{};{}", ToString(s.aspect), ToSeconds(now - s.since),
      ToSeconds(s.min_end - now),
      s.likely_end ? fmt::format(", likely in {:.1f} s", ToSeconds(*s.likely_end - now)) : "",
      heads_text);
  return {{"group", group.id.value()},
          {"name", group.name},
          {"aspect", ToString(s.aspect)},
          {"since_s", Ms(now - s.since)},
          {"min_end_in_s", Ms(s.min_end - now)},
          {"likely_end_in_s",
           s.likely_end ? nlohmann::json(Ms(*s.likely_end - now)) : nlohmann::json()},
          {"heads", std::move(heads)},
          {"text", std::move(text)}};
}

/// An event of the log, as `events` answers it: every field of the record, and `text` for people.
nlohmann::json EventJson(const EventRecord& e) {
  return {{"id", e.id},
          {"stamp", ToSeconds(e.time)},
          {"severity", ToString(e.severity)},
          {"source", e.source},
          {"code", e.code},
          {"message", e.message},
          {"intersection", e.intersection.value()},
          {"device", e.device_id},
          {"actor", e.actor},
          {"active", e.active},
          // The line for people, after the stamp (which scmctl prints as a local date-time).
          {"text", fmt::format("{} {} {}{}{}", ToString(e.severity), e.code, e.message,
                               e.actor.empty() || e.actor == "scm" ? "" : " (by " + e.actor + ")",
                               e.active ? " [active]" : "")}};
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
  auto add = [&](std::string k, nlohmann::json v) {
    r.values.emplace_back(std::move(k), std::move(v));
  };
  add("city", city.config.name);
  add("config", ctx.figures.config_path);
  add("clock", ToString(ctx.figures.clock));
  add("uptime_s", std::round(uptime * 10.0) / 10.0);
  add("lights", ctx.runtime.heads().size());
  add("lights_lost", ctx.supervisor.lost());
  add("events", db.event_count);
  add("events_dropped", db.events_dropped);
  add("hires_written", db.hires_written);
  add("hires_dropped", db.hires_dropped);
  add("database_bytes", db.size_bytes);
  add("spat_published", ctx.publishers.counters().spat);
  add("write_failures", ctx.publishers.counters().write_failures + ctx.lights.counters().failures);
  add("light_commands", ctx.lights.counters().writes);
  add("light_resends", ctx.lights.counters().resends);
  add("requests", cp.received);
  add("refused_invalid", cp.invalid);
  add("refused_rate", cp.rate_limited);
  add("refused_not_allowed", cp.not_allowed);
  add("malformed_requests", cp.invalid + ctx.figures.malformed_inputs);
  add("foreign_devices",
      ctx.supervisor.counters().foreign_city + ctx.supervisor.counters().foreign_host);
  add("signal_requests", ctx.figures.signal_requests);
  add("background_vehicles", ctx.fleet.BackgroundVehicles(now.wire));
  add("monitor_violations", ctx.figures.monitor_violations);
  add("stalls", ctx.figures.stalls);
  add("longest_stall_ms", std::llround(ToSeconds(ctx.figures.longest_stall) * 1000.0));
  // The loop over its last passes (about a minute): how long a pass took, how late it began.
  auto ms = [](Duration d) { return std::round(ToSeconds(d) * 1e6) / 1000.0; };
  add("loop_passes", ctx.figures.loop.size());
  add("loop_work_p50_ms", ms(ctx.figures.loop.WorkQuantile(0.5)));
  add("loop_work_p99_ms", ms(ctx.figures.loop.WorkQuantile(0.99)));
  add("loop_late_p50_ms", ms(ctx.figures.loop.LateQuantile(0.5)));
  add("loop_late_p99_ms", ms(ctx.figures.loop.LateQuantile(0.99)));
  add("reused_request_ids", cp.reused_ids);
  const ReplyCounters& rc = ctx.figures.replies;
  add("replies_sent", rc.sent);
  add("replies_waited_for_reader", rc.waited_for_match);
  add("replies_waited_for_writer", rc.waited_for_writer);
  add("replies_unmatched", rc.unmatched);
  add("replies_dropped", rc.dropped);
  add("reply_write_refusals", ctx.figures.reply_write_refusals);
  return r;
}

std::optional<Reply> Intersections(const OperatorCommand&, const ClockReading&, CommandContext& ctx,
                                   Responder&) {
  Reply r =
      Reply::Ok(fmt::format("{} signalised intersections", ctx.runtime.intersections().size()));
  for (std::size_t i = 0; i < ctx.runtime.intersections().size(); ++i) {
    r.values.emplace_back(ctx.runtime.intersections()[i].model->name,
                          IntersectionValue(ctx.runtime.Summary(i)));
  }
  return r;
}

/// `show X --intergreen`: the intersection's intergreen matrix with its inputs
/// (scm/core/intergreen.h), a value per pair of conflicting groups.
void AddIntergreens(const City& city, const IntersectionModel& x, Reply& r) {
  const SafetyConfig& safety = city.config.safety;
  IntergreenInputs inputs;
  inputs.clearing_vehicles = safety.clearing_vehicles;
  inputs.entering_speed_mps = safety.entering_speed_mps;
  inputs.crossing_time_s = safety.crossing_time_s;
  nlohmann::json vehicles = nlohmann::json::array();
  for (const ClearingVehicleConfig& v : inputs.clearing_vehicles) {
    vehicles.push_back({{"name", v.name}, {"length_m", v.length_m}, {"speed_mps", v.speed_mps}});
  }
  const double reach = city.map.lane_width_m / 2.0;
  r.values.emplace_back(
      "intergreen inputs",
      nlohmann::json{
          {"clearing_vehicles", vehicles},
          {"entering_speed_mps", inputs.entering_speed_mps},
          {"crossing_time_s", inputs.crossing_time_s},
          {"conflict_reach_m", reach},
          {"text", fmt::format("t = t_cross {:.1f} s + (s_clear + L) / v_clear - s_enter / {:.2f} "
                               "m/s; paths conflict within {:.2f} m (half a lane); clearing: {}",
                               inputs.crossing_time_s, inputs.entering_speed_mps, reach,
                               fmt::join(safety.clearing_vehicles |
                                             std::views::transform([](const auto& v) {
                                               return fmt::format("{} {:.3f} m at {:.2f} m/s",
                                                                  v.name, v.length_m, v.speed_mps);
                                             }),
                                         ", "))}});
  const auto matrix = ComputeIntergreens(city.map, x, inputs);
  for (const auto& row : matrix) {
    for (const auto& e : row) {
      if (!e) continue;
      const SignalGroup& a = x.groups[e->clearing];
      const SignalGroup& b = x.groups[e->entering];
      const std::string& ma = city.map.movement(e->clearing_movement).name;
      const std::string& mb = city.map.movement(e->entering_movement).name;
      r.values.emplace_back(
          fmt::format("intergreen {} > {}", a.id.value(), b.id.value()),
          nlohmann::json{
              {"clearing_group", a.id.value()},
              {"entering_group", b.id.value()},
              {"intergreen_s", e->intergreen_s},
              {"ite_s", e->ite_s},
              {"clearing_movement", ma},
              {"entering_movement", mb},
              {"vehicle", e->vehicle},
              {"clearing_path_m", e->clearing_path_m},
              {"entering_path_m", e->entering_path_m},
              {"clearing_time_s", e->clearing_time_s},
              {"entering_time_s", e->entering_time_s},
              {"text", fmt::format("{} ({}) > {} ({}): {:.1f} s = {:.1f} + ({:.2f} + {:.3f}) / "
                                   "{:.2f} - {:.2f} / {:.2f} ({} clearing {}, {} entering); ITE "
                                   "(W + L) / V {:.1f} s",
                                   a.id.value(), a.name, b.id.value(), b.name, e->intergreen_s,
                                   e->crossing_time_s, e->clearing_path_m, e->vehicle_length_m,
                                   e->clearing_speed_mps, e->entering_path_m,
                                   inputs.entering_speed_mps, e->vehicle, ma, mb, e->ite_s)}});
    }
  }
}

std::optional<Reply> Show(const OperatorCommand& cmd, const ClockReading& now, CommandContext& ctx,
                          Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  const IntersectionRuntime& x = ctx.runtime.intersections()[*xi];
  Reply r = Reply::Ok(x.model->name + ": " + Describe(ctx.runtime.Summary(*xi)));
  const auto signals = x.controller->Signals(now.mono);
  for (std::size_t g = 0; g < signals.size(); ++g) {
    const SignalGroup& group = x.model->groups[g];
    r.values.emplace_back(fmt::format("group {} {}", group.id.value(), group.name),
                          GroupJson(group, signals[g], now.mono, ctx));
  }
  // Vehicles on each approach (its ingress lanes and the box's movements from it).
  const maps::Intersection& mx = ctx.runtime.city().map.intersection(x.model->id);
  for (const ApproachCount& a : ctx.fleet.ApproachCounts(x.model->id, now.wire)) {
    const auto it = std::ranges::find(mx.approaches, a.approach, &maps::Approach::id);
    const std::string_view side = ApproachName(it->side);
    r.values.emplace_back(fmt::format("approach {}", side),
                          nlohmann::json{{"approach", side},
                                         {"lab", a.lab},
                                         {"background", a.background},
                                         {"text", fmt::format("{} lab, {} background vehicles",
                                                              a.lab, a.background)}});
  }
  if (ctx.supervisor.monitor_seen(*xi)) {
    r.values.emplace_back("infrastructure monitor",
                          ctx.supervisor.monitor_latched(*xi) ? "latched" : "watching");
  }
  for (const PhaseControl& pc : x.controller->controls().all()) {
    const Plan& plan = x.model->plans[pc.plan];
    const double left = pc.once ? 0.0 : ToSeconds(pc.until - now.mono);
    r.values.emplace_back(
        fmt::format("{} phase {} {}", ToString(pc.kind), pc.phase + 1, plan.name),
        nlohmann::json{
            {"control", ToString(pc.kind)},
            {"phase", pc.phase + 1},
            {"plan", plan.name},
            {"left_s", pc.once ? nlohmann::json(nullptr) : nlohmann::json(left)},
            {"text", pc.once ? fmt::format("{} phase {} of plan {} until its green ends",
                                           ToString(pc.kind), pc.phase + 1, plan.name)
                             : fmt::format("{} phase {} of plan {} for {:.1f} s more{}",
                                           ToString(pc.kind), pc.phase + 1, plan.name, left,
                                           pc.plan == x.controller->plan_index()
                                               ? ""
                                               : " (when that plan runs)")}});
  }
  if (cmd.Arg("intergreen") == "true") AddIntergreens(ctx.runtime.city(), *x.model, r);
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
  if (auto state = ctx.runtime.TakeStateToSave(xi, now)) {
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

/// Parses the whole of `text` as a number into `out`; false when it is not one.
template <typename T>
bool ParseWhole(const std::string& text, T& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc() && end == text.data() + text.size() && !text.empty();
}

/// `phase_control`: an omit, ped omit, hold, force-off, call or ped call on a phase of the
/// running plan for `for_s` seconds, or taken off with `off` (docs/controller.md, "Phase
/// controls").
std::optional<Reply> PhaseControlCommand(const OperatorCommand& cmd, const ClockReading& now,
                                         CommandContext& ctx, Responder&) {
  Reply error;
  const auto xi = Intersection(cmd, ctx, error);
  if (!xi) return error;
  const auto kind = PhaseControlFromString(cmd.Arg("control"));
  if (!kind) {
    return Reply::Invalid(
        fmt::format("unknown phase control \"{}\" ({})", cmd.Arg("control"), PhaseControlNames()));
  }
  std::size_t phase = 0;
  if (!ParseWhole(cmd.Arg("phase"), phase) || phase == 0) {
    return Reply::Invalid(
        fmt::format("phase must be a phase number (1, 2, ...), got \"{}\"", cmd.Arg("phase")));
  }
  auto& c = *ctx.runtime.intersections()[*xi].controller;
  if (cmd.Arg("off") == "true")
    return Changed(cmd, *xi, c.ClearControl(*kind, phase, now.mono), now, ctx);
  double for_s = 0;
  const double most = ToSeconds(IntersectionController::kMaxPhaseControl);
  if (!ParseWhole(cmd.Arg("for_s"), for_s) || !std::isfinite(for_s) || for_s <= 0 || for_s > most) {
    return Reply::Invalid(fmt::format(
        "for_s must be the control's duration in seconds, more than 0 and at most {:.0f}, got "
        "\"{}\" (or off: true to take it off)",
        most, cmd.Arg("for_s")));
  }
  const auto duration = std::chrono::duration_cast<Duration>(std::chrono::duration<double>(for_s));
  return Changed(cmd, *xi, c.Control(*kind, phase, duration, now.mono), now, ctx);
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
  ctx.persistence.QueryEvents(
      q, [respond = std::move(respond)](std::vector<EventRecord> events, std::string error) {
        if (!error.empty()) {
          respond(Reply::Failed("cannot read the event log: " + error));
          return;
        }
        Reply r = Reply::Ok(fmt::format("{} events", events.size()));
        for (const auto& e : events) r.values.emplace_back(std::to_string(e.id), EventJson(e));
        respond(std::move(r));
      });
  return std::nullopt;
}

/// `hires`: intersection X's high-resolution log from `since` to `until` (seconds since the
/// epoch; until absent: now), at most `limit` records (1..100000, default 100000), as one value
/// "records": [[milliseconds since the epoch, code, param], ...] in time order.
std::optional<Reply> Hires(const OperatorCommand& cmd, const ClockReading& now, CommandContext& ctx,
                           Responder& respond) {
  Reply refusal;
  const auto xi = Intersection(cmd, ctx, refusal);
  if (!xi) return refusal;
  HiresQuery q;
  q.intersection = ctx.runtime.intersections()[*xi].model->id;
  q.until = now.wire + std::chrono::seconds(1);
  for (const auto& [key, into] : {std::pair{"since", &q.since}, std::pair{"until", &q.until}}) {
    const std::string& text = cmd.Arg(key);
    if (text.empty()) {
      if (std::string_view(key) == "since") {
        return Reply::Invalid("hires needs since (seconds since the epoch)");
      }
      continue;
    }
    double seconds = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), seconds);
    if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(seconds)) {
      return Reply::Invalid(
          fmt::format("{} must be seconds since the epoch, got \"{}\"", key, text));
    }
    // To the millisecond, as the records go out (a client pages by a record's millisecond).
    *into = Time(std::chrono::milliseconds(std::llround(seconds * 1000.0)));
  }
  if (q.until < q.since) return Reply::Invalid("until is before since");
  if (!cmd.Arg("limit").empty()) {
    const std::string& text = cmd.Arg("limit");
    std::size_t limit = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), limit);
    if (ec != std::errc() || end != text.data() + text.size() || limit == 0 || limit > 100000) {
      return Reply::Invalid(fmt::format("limit must be a number in 1..100000, got \"{}\"", text));
    }
    q.limit = limit;
  }
  const std::string name = ctx.runtime.intersections()[*xi].model->name;
  ctx.persistence.QueryHires(
      q, [respond = std::move(respond), name](std::vector<HiresRecord> records, std::string error) {
        if (!error.empty()) {
          respond(Reply::Failed("cannot read the high-resolution log: " + error));
          return;
        }
        Reply r = Reply::Ok(fmt::format("{}: {} records", name, records.size()));
        nlohmann::json rows = nlohmann::json::array();
        for (const HiresRecord& h : records) {
          const auto ms =
              std::chrono::duration_cast<std::chrono::milliseconds>(h.time.time_since_epoch());
          rows.push_back({ms.count(), h.code, h.param});
        }
        r.values.emplace_back("records", std::move(rows));
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
    {"status", Status},   {"intersections", Intersections},
    {"show", Show},       {"events", Events},
    {"hires", Hires},     {"config_validate", ConfigValidate},
    {"mode", SetMode},    {"plan", SetPlan},
    {"advance", Advance}, {"phase_control", PhaseControlCommand},
    {"reset", Reset},     {"config_apply", ConfigApply},
};

}  // namespace

ReplyValue IntersectionValue(const IntersectionSummary& s) {
  std::string out;
  out.reserve(192);
  fmt::format_to(std::back_inserter(out), R"({{"id":{},"mode":"{}","requested":"{}","plan":)",
                 s.id.value(), ToString(s.mode), ToString(s.requested));
  AppendJsonString(s.plan, out);
  fmt::format_to(std::back_inserter(out), R"(,"plan_by":"{}","stage":"{}","latched":)",
                 s.plan_by_operator ? "operator" : "schedule", ToString(s.stage));
  if (s.latched) {
    AppendJsonString(*s.latched, out);
  } else {
    out += "null";
  }
  out += R"(,"pending_plan":)";
  if (s.pending_plan) {
    AppendJsonString(*s.pending_plan, out);
  } else {
    out += "null";
  }
  out += R"(,"text":)";
  AppendJsonString(Describe(s), out);
  out += '}';
  return ReplyValue::FromJsonText(std::move(out));
}

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
