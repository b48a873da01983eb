// autodrive-live checked as Lichtblick connects to it: through @foxglove/ws-protocol's
// FoxgloveClient (the client class Lichtblick's FoxgloveWebSocketPlayer uses) over the `ws`
// WebSocket, with every advertised schema parsed by @foxglove/rosmsg (parse(schema, {ros2: true}))
// and payloads decoded by @foxglove/rosmsg2-serialization's MessageReader. Run by
// tests/ros2/live_city.py (CTest: tests/ros2/live_tests.cmake). Times are this process's wall
// clock in ns (performance.timeOrigin + performance.now()), comparable with DDS source times on
// the same host.
//
//   node check_live.mjs handshake URL OUT [--layout FILE]
//     Connects with each subprotocol alone and with Lichtblick's offer of both; notes the
//     subprotocol answered and the time from the connection's open to serverInfo. On one
//     connection: the advertised channels (each schema parsed), then misbehaves (malformed JSON,
//     an unknown op, a client advertise, a client message, a subscription to a channel that does
//     not exist, a duplicate subscription id) and notes each status answer; then subscribes to
//     every channel, decodes the first message of each and unsubscribes it (topics silent for
//     the window are listed). With --layout, every message path of the Lichtblick layout FILE
//     (Plot paths, RawMessages topic paths) is resolved against its topic's advertised schema:
//     the topic advertised, each field there, `[n]`/`[:]` only on arrays, `{field==value}` on
//     messages with that field, and a Plot path ending in a number. Writes {connects, channels,
//     statuses, decoded, silent, layout_paths, errors}.
//
//   node check_live.mjs stream URL TOPIC SECONDS OUT [--wait-stdin]
//     Subscribes to TOPIC, notes every message (client receive time, messageData timestamp,
//     payload hex; each decoded), unsubscribes after SECONDS and prints "unsubscribed <ns>";
//     with --wait-stdin it then waits for a line on stdin (the driver's "done"), and at least 1 s
//     more, noting what still arrives. Writes {topic, messages, unsubscribed_ns, after, errors}.
//
//   node check_live.mjs load URL CLIENTS OUT
//     CLIENTS clients each subscribe to every channel except images; prints "subscribed" once
//     every client has had a message; counts until a line on stdin; writes {clients: [counts]}.
//
// Exit status 1 when a check of its own fails (errors non-empty), 2 on usage.

import fs from "node:fs";
import readline from "node:readline";

import wsProtocol from "@foxglove/ws-protocol";
import rosmsg from "@foxglove/rosmsg";
import serialization from "@foxglove/rosmsg2-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const { parse } = rosmsg;
const { MessageReader } = serialization;

const nowNs = () => BigInt(Math.round((performance.timeOrigin + performance.now()) * 1e6));
const hex = (view) =>
  Buffer.from(view.buffer, view.byteOffset, view.byteLength).toString("hex");
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

function usage(message) {
  console.error(`check_live.mjs: ${message}`);
  process.exit(2);
}

/// Resolves when `predicate()` holds (checked every 20 ms) or rejects after `ms`.
async function until(predicate, ms, what) {
  const deadline = Date.now() + ms;
  while (!predicate()) {
    if (Date.now() > deadline) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await sleep(20);
  }
}

/// A FoxgloveClient over `ws` offering `protocols`, with what it has seen so far.
function connect(url, protocols) {
  const ws = new WebSocket(url, protocols);
  const client = new FoxgloveClient({ ws });
  const state = { ws, client, open: false, closed: false, error: null, openNs: 0n,
                  serverInfo: null, serverInfoNs: 0n, channels: new Map(), statuses: [] };
  client.on("open", () => { state.open = true; state.openNs = nowNs(); });
  client.on("close", () => { state.closed = true; });
  client.on("error", (e) => { state.error = String(e?.message ?? e); });
  client.on("serverInfo", (info) => { state.serverInfo = info; state.serverInfoNs = nowNs(); });
  client.on("status", (s) => state.statuses.push(s));
  client.on("advertise", (cs) => { for (const c of cs) state.channels.set(c.id, c); });
  client.on("unadvertise", (ids) => { for (const id of ids) state.channels.delete(id); });
  return state;
}

/// Why the message path `path` does not resolve against the advertised channels; null when it
/// does (Lichtblick's syntax: TOPIC.field[n].field{field=="value"}[:].field).
function pathProblem(path, channelsByTopic, plotted) {
  const start = path.search(/[.{[]/);
  const topic = start < 0 ? path : path.slice(0, start);
  const channel = channelsByTopic.get(topic);
  if (channel === undefined) return `${topic} is not advertised`;
  const definitions = parse(channel.schema, { ros2: true });
  const byName = new Map(definitions.map((d) => [d.name, d]));
  // rosmsg reads builtin_interfaces Time and Duration as the primitives time and duration, which
  // Lichtblick's paths (and MessageReader's output) open as {sec, nsec}.
  for (const t of ["time", "duration"]) {
    byName.set(t, { name: t, definitions: [{ name: "sec", type: "int32" },
                                           { name: "nsec", type: "uint32" }] });
  }
  let message = definitions[0];  // the current message, or undefined when at a field
  let field;  // the current field, when at one
  let inArray = false;  // at an array field, not yet indexed
  const tokens = path.slice(topic.length).match(/\.[A-Za-z_]\w*|\[(?:\d+|:)\]|\{[A-Za-z_]\w*==(?:"[^"]*"|[-\d.]+)\}/g) ?? [];
  if (tokens.join("") !== path.slice(topic.length)) return `cannot read the path ${path}`;
  for (const token of tokens) {
    if (token.startsWith(".")) {
      if (message === undefined || inArray) return `${token} on a non-message in ${path}`;
      field = message.definitions.find((d) => d.name === token.slice(1) && !d.isConstant);
      if (field === undefined) return `no field ${token.slice(1)} in ${message.name ?? topic}`;
      inArray = field.isArray === true;
      message = !inArray && (field.isComplex || byName.has(field.type)) ? byName.get(field.type)
                                                                          : undefined;
    } else if (token.startsWith("[")) {
      if (!inArray) return `${token} on a field that is not an array in ${path}`;
      inArray = false;
      message = field.isComplex || byName.has(field.type) ? byName.get(field.type) : undefined;
    } else {
      const name = token.slice(1, token.indexOf("=="));
      if (message === undefined || !message.definitions.some((d) => d.name === name)) {
        return `filter ${token} on a message without ${name} in ${path}`;
      }
    }
  }
  if (plotted) {
    const numeric = field !== undefined && !inArray && message === undefined &&
      /^(u?int(8|16|32|64)|float(32|64)|bool|byte|char)$/.test(field.type);
    if (!numeric) return `${path} does not end in a number`;
  }
  return null;
}

function readerFor(channel) {
  return new MessageReader(parse(channel.schema, { ros2: true }));
}

async function handshake(url, out, layoutFile) {
  const result = { connects: [], channels: [], statuses: [], decoded: [], silent: [],
                   layout_paths: [], errors: [] };
  for (const protocols of [["foxglove.websocket.v1"], ["foxglove.sdk.v1"],
                           ["foxglove.websocket.v1", "foxglove.sdk.v1"]]) {
    const c = connect(url, protocols);
    try {
      await until(() => c.serverInfo !== null || c.closed, 30000, "serverInfo");
    } catch (e) {
      result.errors.push(`${protocols}: ${e.message}`);
    }
    result.connects.push({
      offered: protocols, answered: c.ws.protocol,
      serverinfo_ms: c.serverInfo ? Number(c.serverInfoNs - c.openNs) / 1e6 : null,
      capabilities: c.serverInfo?.capabilities ?? null, name: c.serverInfo?.name ?? null });
    c.client.close();
  }

  const c = connect(url, ["foxglove.websocket.v1"]);
  await until(() => c.serverInfo !== null && c.channels.size > 0, 30000, "serverInfo and advertise");
  const readers = new Map();
  for (const channel of c.channels.values()) {
    const entry = { id: channel.id, topic: channel.topic, schemaName: channel.schemaName,
                    encoding: channel.encoding, schemaEncoding: channel.schemaEncoding };
    try {
      readers.set(channel.id, readerFor(channel));
      entry.schema_parsed = true;
    } catch (e) {
      entry.schema_parsed = false;
      result.errors.push(`${channel.topic}: schema does not parse: ${e.message}`);
    }
    result.channels.push(entry);
  }

  if (layoutFile) {
    const byTopic = new Map([...c.channels.values()].map((ch) => [ch.topic, ch]));
    const layout = JSON.parse(fs.readFileSync(layoutFile, "utf8"));
    for (const panel of Object.values(layout.configById)) {
      const paths = (panel.paths ?? []).map((p) => [p.value, true]);
      if (panel.topicPath) paths.push([panel.topicPath, false]);
      for (const [path, plotted] of paths) {
        const problem = pathProblem(path, byTopic, plotted);
        result.layout_paths.push({ path, problem });
        if (problem) result.errors.push(`${layoutFile}: ${problem}`);
      }
    }
    // The check itself: paths that must not resolve.
    for (const bad of ["/autodrive/scm/spat.no_such_field", "/autodrive/scm/spat.intersections.name",
                       "/autodrive/scm/spat.header[0]", "/autodrive/scm/spat.intersections[0]",
                       "/autodrive/scm/fleet.vehicles[:]{no_such==1}.tag_id", "/no/such/topic"]) {
      if (pathProblem(bad, byTopic, true) === null) {
        result.errors.push(`the layout check accepts the bad path ${bad}`);
      }
    }
  }

  // Misbehaviour, one at a time, each answered by a status.
  const misbehave = [
    ["malformed JSON", () => c.ws.send("{not json")],
    ["unknown op", () => c.ws.send(JSON.stringify({ op: "teleport" }))],
    ["client advertise", () => c.client.advertise({ topic: "/autodrive/scm/spat", encoding: "cdr",
                                                    schemaName: "autodrive_msgs/msg/Spat" })],
    ["client message", () => c.client.sendMessage(1, new Uint8Array([0, 1, 0, 0]))],
    ["subscribe to a channel not advertised", () => c.ws.send(JSON.stringify(
      { op: "subscribe", subscriptions: [{ id: 900, channelId: 999999 }] }))],
    ["unsubscribe an unknown id", () => c.ws.send(JSON.stringify(
      { op: "unsubscribe", subscriptionIds: [901] }))],
  ];
  for (const [what, act] of misbehave) {
    const before = c.statuses.length;
    act();
    try {
      await until(() => c.statuses.length > before || c.closed, 10000, `a status for ${what}`);
    } catch (e) {
      result.errors.push(e.message);
    }
    const s = c.statuses[before];
    result.statuses.push({ what, level: s?.level ?? null, message: s?.message ?? null });
  }
  if (c.closed) result.errors.push("the server closed the connection after the misbehaviour");

  // Every channel: its first message decoded, then unsubscribed. The topics but images at once,
  // then each image topic alone (two 6 MB frames at once would overflow the client's queue and
  // push out a latched message queued before them).
  const pending = new Map();
  c.client.on("message", ({ subscriptionId, data }) => {
    const channel = pending.get(subscriptionId);
    if (channel === undefined) return;
    pending.delete(subscriptionId);
    c.client.unsubscribe(subscriptionId);
    const reader = readers.get(channel.id);
    try {
      reader.readMessage(data);
      result.decoded.push({ topic: channel.topic, bytes: data.byteLength });
    } catch (e) {
      result.errors.push(`${channel.topic}: a message does not decode: ${e.message}`);
    }
  });
  const parsed = [...c.channels.values()].filter((ch) => readers.has(ch.id));
  const isImage = (ch) => ch.schemaName === "sensor_msgs/msg/Image";
  const silent = [];
  for (const group of [parsed.filter((ch) => !isImage(ch)),
                       ...parsed.filter(isImage).map((ch) => [ch])]) {
    for (const channel of group) pending.set(c.client.subscribe(channel.id), channel);
    // Latched and periodic topics answer within seconds; some (commands, requests) only when
    // used.
    const start = Date.now();
    while (pending.size > 0 && Date.now() - start < 15000 && !c.closed) await sleep(50);
    for (const [sub, channel] of pending) {
      silent.push(channel.topic);
      c.client.unsubscribe(sub);
    }
    pending.clear();
  }
  result.silent = silent.sort();
  c.client.close();
  fs.writeFileSync(out, JSON.stringify(result));
  return result.errors.length === 0;
}

async function stream(url, topic, seconds, out, waitStdin) {
  const result = { topic, messages: [], after: [], unsubscribed_ns: null, errors: [] };
  const c = connect(url, ["foxglove.websocket.v1", "foxglove.sdk.v1"]);
  await until(() => [...c.channels.values()].some((ch) => ch.topic === topic), 30000,
              `${topic} advertised`);
  const channel = [...c.channels.values()].find((ch) => ch.topic === topic);
  const reader = readerFor(channel);
  let unsubscribed = false;
  c.client.on("message", ({ subscriptionId, timestamp, data }) => {
    const m = { recv_ns: nowNs().toString(), ts_ns: timestamp.toString(), hex: hex(data),
                sub: subscriptionId };
    try {
      reader.readMessage(data);
    } catch (e) {
      result.errors.push(`${topic}: does not decode: ${e.message}`);
    }
    (unsubscribed ? result.after : result.messages).push(m);
  });
  const sub = c.client.subscribe(channel.id);
  await sleep(seconds * 1000);  // the measurement's window
  c.client.unsubscribe(sub);
  unsubscribed = true;
  result.unsubscribed_ns = nowNs().toString();
  console.log(`unsubscribed ${result.unsubscribed_ns}`);
  const quiet = sleep(1000);  // at least 1 s after the unsubscription is watched
  if (waitStdin) {
    const lines = readline.createInterface({ input: process.stdin });
    await new Promise((resolve) => lines.once("line", resolve));
    lines.close();
  }
  await quiet;
  if (c.closed) result.errors.push("the connection closed");
  c.client.close();
  fs.writeFileSync(out, JSON.stringify(result));
  return result.errors.length === 0;
}

async function load(url, n, out) {
  const clients = [];
  for (let i = 0; i < n; i++) clients.push(connect(url, ["foxglove.websocket.v1"]));
  await until(() => clients.every((c) => c.serverInfo !== null && c.channels.size > 0), 60000,
              "every client's advertise");
  const counts = clients.map(() => 0);
  clients.forEach((c, i) => {
    c.client.on("message", () => { counts[i]++; });
    for (const channel of c.channels.values()) {
      if (channel.schemaName !== "sensor_msgs/msg/Image") c.client.subscribe(channel.id);
    }
  });
  await until(() => counts.every((k) => k > 0), 60000, "a message on every client");
  console.log("subscribed");
  const lines = readline.createInterface({ input: process.stdin });
  await new Promise((resolve) => lines.once("line", resolve));
  lines.close();
  const closed = clients.filter((c) => c.closed).length;
  for (const c of clients) c.client.close();
  fs.writeFileSync(out, JSON.stringify({ clients: counts, closed }));
  return closed === 0;
}

const [mode, url, ...rest] = process.argv.slice(2);
let ok;
if (mode === "handshake" && (rest.length === 1 || (rest.length === 3 && rest[1] === "--layout"))) {
  ok = await handshake(url, rest[0], rest[2]);
} else if (mode === "stream" && rest.length >= 3) {
  ok = await stream(url, rest[0], Number(rest[1]), rest[2], rest.includes("--wait-stdin"));
} else if (mode === "load" && rest.length === 2) {
  ok = await load(url, Number(rest[0]), rest[1]);
} else {
  usage("usage: check_live.mjs handshake URL OUT [--layout FILE] | stream URL TOPIC SECONDS OUT [--wait-stdin] | "
        + "load URL CLIENTS OUT");
}
process.exit(ok ? 0 : 1);
