// An MCAP recording of autodrive-record checked with the npm libraries Lichtblick uses (issue 35):
// @mcap/core reads it indexed (McapIndexedReader, chunk CRCs validated) and streamed
// (McapStreamReader with validateCrcs), and every message is decoded with its own channel's
// schema by @foxglove/rosmsg (parse(schema, {ros2: true})) and @foxglove/rosmsg2-serialization.
// Run by CTest (tests/ros2/mcap_tests.cmake):
//
//   node check_mcap.mjs FILE [--expect TOPIC[:MIN_COUNT]]... [--flip-byte OFFSET|middle] [--foreign]
//                      [--times OUT] [--values OUT]
//
// Checks: profile ros2; a Statistics record whose per-channel counts equal the messages the
// indexed and the streamed reading find; the data section's CRC (recomputed here) equals
// DataEnd's; schemas `ros2msg` named pkg/msg/Type, channels `cdr`; every message decodes (0
// errors); each channel's `offered_qos_profiles` parses as a list with rosbag2's keys and its
// `topic_type_hash` is RIHS01_<64 hex>; the `rosbag2` metadata record is version 8, storage mcap,
// with the same total count; every --expect topic is there with at least MIN_COUNT messages.
// Prints {profile, messages, duration_s, topics: {name: {type, count, rate_hz, payload_sha256,
// offered}}, errors} as JSON (offered: the distinct "reliability R, durability D" of its writers) (payload_sha256: over the topic's payloads in order, each after its length);
// exit status 1 when any check fails.
//
// --foreign: the file was written by another program (rosbag2): a data section CRC and the
// rosbag2 metadata record are checked when present, not required, and any metadata version
// passes.
//
// --times OUT: writes each message's publish time (the DDS source time) and log time (received),
// in nanoseconds, to OUT as one JSON line per topic: {"topic", "publish": [...], "log": [...]},
// for comparing a recording with another subscriber over the same window.
//
// --values OUT: writes every decoded message of the topics of std_msgs/msg/Int32 and
// autodrive_msgs/msg/DeviceStatus (lamp states, device statuses) to OUT, one JSON line each:
// {"topic", "publish" (ns), "message"}: what a light host showed, read back from its recording
// (tests/netns/lab_link_cut.py).
//
// --flip-byte: checks a copy (in memory) with one byte changed, at OFFSET or in the middle of the
// first chunk's records: the check must then fail (the test that runs it expects exit 1).

import crypto from "node:crypto";
import fs from "node:fs";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import rosmsg from "@foxglove/rosmsg";
import serialization from "@foxglove/rosmsg2-serialization";

const { parse } = rosmsg;
const { MessageReader } = serialization;

function usage(message) {
  console.error(`check_mcap.mjs: ${message}`);
  console.error("usage: node check_mcap.mjs FILE [--expect TOPIC[:MIN]]... [--flip-byte N|middle] [--foreign] [--times OUT] [--values OUT]");
  process.exit(2);
}

let file = "";
const expect = [];
let flip = null;
let foreign = false;
let timesFile = null;
let valuesFile = null;
const valueTypes = new Set(["std_msgs/msg/Int32", "autodrive_msgs/msg/DeviceStatus"]);
for (let i = 2; i < process.argv.length; i++) {
  const arg = process.argv[i];
  if (arg === "--expect") {
    const value = process.argv[++i] ?? usage("--expect needs TOPIC[:MIN]");
    const colon = value.lastIndexOf(":");
    expect.push(colon > 0 ? { topic: value.slice(0, colon), min: Number(value.slice(colon + 1)) }
                          : { topic: value, min: 1 });
  } else if (arg === "--flip-byte") {
    flip = process.argv[++i] ?? usage("--flip-byte needs an offset or 'middle'");
  } else if (arg === "--times") {
    timesFile = process.argv[++i] ?? usage("--times needs a file");
  } else if (arg === "--values") {
    valuesFile = process.argv[++i] ?? usage("--values needs a file");
  } else if (arg === "--foreign") {
    foreign = true;
  } else if (arg.startsWith("-")) {
    usage(`unknown option ${arg}`);
  } else {
    file = arg;
  }
}
if (!file) usage("no file");

// The file is read in pieces (a recording with a camera runs to gigabytes, past what one Buffer
// holds); only --flip-byte reads it whole, to change a byte of a copy in memory.
const errors = [];
const fileSize = fs.statSync(file).size;
const handle = fs.openSync(file, "r");
let bytes = null;
function readAt(offset, size) {
  if (bytes !== null) return bytes.subarray(offset, offset + size);
  const out = new Uint8Array(size);
  let done = 0;
  while (done < size) {
    const n = fs.readSync(handle, out, done, size - done, offset + done);
    if (n === 0) throw new Error(`read past the end (${offset}+${size})`);
    done += n;
  }
  return out;
}
const kPiece = 16 << 20;

// CRC-32 (IEEE), written here so as not to trust the library's own.
const crcTable = new Uint32Array(256).map((_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});
function crc32Update(c, data) {
  for (let i = 0; i < data.length; i++) c = crcTable[(c ^ data[i]) & 0xff] ^ (c >>> 8);
  return c;
}
/// The CRC of the file's first `length` bytes, read in pieces.
function crc32Prefix(length) {
  let c = 0xffffffff;
  for (let at = 0; at < length; at += kPiece) c = crc32Update(c, readAt(at, Math.min(kPiece, length - at)));
  return (c ^ 0xffffffff) >>> 0;
}

async function indexedReader() {
  return McapIndexedReader.Initialize({
    readable: {
      size: async () => BigInt(fileSize),
      read: async (offset, size) => {
        if (offset + size > BigInt(fileSize)) throw new Error(`read past the end (${offset}+${size})`);
        return readAt(Number(offset), Number(size));
      },
    },
  });
}

if (flip !== null) {
  bytes = new Uint8Array(fs.readFileSync(file));
  let offset;
  if (flip === "middle") {
    const reader = await indexedReader();
    const chunk = reader.chunkIndexes[0];
    if (!chunk) usage("--flip-byte middle: the file has no chunk");
    offset = Number(chunk.chunkStartOffset + chunk.chunkLength / 2n);
  } else {
    offset = Number(flip);
  }
  bytes[offset] ^= 0x5a;
  console.error(`check_mcap.mjs: byte ${offset} flipped`);
}

/// Minimal reader of rosbag2's offered_qos_profiles YAML: a list of mappings whose values are
/// integers, booleans or one level of nested {sec, nsec}.
function parseQosProfiles(text) {
  const profiles = [];
  let nested = null;
  for (const raw of text.split("\n")) {
    if (!raw.trim() || raw.trim() === "[]") continue;
    let line = raw;
    if (line.startsWith("- ")) {
      profiles.push({});
      line = "  " + line.slice(2);
    }
    if (profiles.length === 0) throw new Error(`not a list: '${raw}'`);
    const m = /^( *)([a-z_]+):\s*(.*)$/.exec(line);
    if (!m) throw new Error(`no 'key: value' in '${raw}'`);
    const [, indent, key, value] = m;
    const profile = profiles[profiles.length - 1];
    if (indent.length === 2) {
      if (value === "") {
        nested = profile[key] = {};
      } else {
        profile[key] = value === "true" ? true : value === "false" ? false : Number(value);
        nested = null;
      }
    } else if (nested) {
      nested[key] = Number(value);
    } else {
      throw new Error(`unexpected indentation in '${raw}'`);
    }
  }
  return profiles;
}
const qosKeys = ["history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
                 "liveliness_lease_duration", "avoid_ros_namespace_conventions"];

const result = { file, profile: "", library: "", messages: 0, chunks: 0, duration_s: 0, topics: {}, errors };
try {
  const reader = await indexedReader();
  result.profile = reader.header.profile;
  result.library = reader.header.library;
  if (reader.header.profile !== "ros2") errors.push(`profile '${reader.header.profile}', not ros2`);
  const stats = reader.statistics;
  if (!stats) throw new Error("no Statistics record (rosbag2 needs it)");
  result.messages = Number(stats.messageCount);
  result.chunks = stats.chunkCount;
  result.duration_s = Number(stats.messageEndTime - stats.messageStartTime) / 1e9;

  // The data section's CRC, recomputed.
  if (reader.dataSectionCrc !== undefined) {
    const crc = crc32Prefix(Number(reader.dataEndOffset));
    if (crc !== reader.dataSectionCrc) errors.push(`data section CRC ${crc}, DataEnd says ${reader.dataSectionCrc}`);
  } else if (!foreign) {
    errors.push("DataEnd has no data section CRC");
  }

  // Schemas and channels.
  const decoders = new Map();
  for (const [id, channel] of reader.channelsById) {
    const schema = reader.schemasById.get(channel.schemaId);
    const where = `channel ${channel.topic}`;
    if (!schema) { errors.push(`${where}: no schema ${channel.schemaId}`); continue; }
    if (schema.encoding !== "ros2msg") errors.push(`${where}: schema encoding ${schema.encoding}`);
    if (!/^\w+\/msg\/\w+$/.test(schema.name)) errors.push(`${where}: schema name ${schema.name}`);
    if (channel.messageEncoding !== "cdr") errors.push(`${where}: message encoding ${channel.messageEncoding}`);
    try {
      decoders.set(id, new MessageReader(parse(new TextDecoder().decode(schema.data), { ros2: true })));
    } catch (e) {
      errors.push(`${where}: schema ${schema.name} does not parse: ${e.message}`);
    }
    const hash = channel.metadata.get("topic_type_hash");
    if (!/^RIHS01_[0-9a-f]{64}$/.test(hash ?? "")) errors.push(`${where}: topic_type_hash '${hash}'`);
    // The writers' reliability and durability as rosbag2 numbers them ("1 reliable", ...).
    let offered = [];
    try {
      const profiles = parseQosProfiles(channel.metadata.get("offered_qos_profiles") ?? "");
      if (profiles.length === 0) errors.push(`${where}: offered_qos_profiles is empty`);
      for (const p of profiles) {
        for (const k of qosKeys) if (!(k in p)) errors.push(`${where}: offered_qos_profiles lacks ${k}`);
      }
      offered = [...new Set(profiles.map((p) => `reliability ${p.reliability}, durability ${p.durability}`))].sort();
    } catch (e) {
      errors.push(`${where}: offered_qos_profiles: ${e.message}`);
    }
    result.topics[channel.topic] = { type: schema.name, count: 0, rate_hz: 0, decode_errors: 0, offered };
  }

  // Every message, indexed, decoded with its channel's schema.
  const first = new Map();
  const last = new Map();
  const indexedCounts = new Map();
  const digests = new Map();
  const times = new Map();  // channel id -> {publish: [], log: []}, for --times
  const values = [];  // JSON lines, for --values
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const channel = reader.channelsById.get(m.channelId);
    const topic = result.topics[channel.topic];
    indexedCounts.set(m.channelId, (indexedCounts.get(m.channelId) ?? 0) + 1);
    // The payloads in order, each with its length: equal digests, byte-identical payloads.
    if (!digests.has(m.channelId)) digests.set(m.channelId, crypto.createHash("sha256"));
    const length = Buffer.alloc(4);
    length.writeUInt32LE(m.data.length);
    digests.get(m.channelId).update(length).update(m.data);
    topic.count++;
    if (timesFile !== null) {
      if (!times.has(m.channelId)) times.set(m.channelId, { publish: [], log: [] });
      times.get(m.channelId).publish.push(m.publishTime.toString());
      times.get(m.channelId).log.push(m.logTime.toString());
    }
    if (!first.has(m.channelId)) first.set(m.channelId, m.logTime);
    last.set(m.channelId, m.logTime);
    try {
      const decoded = decoders.get(m.channelId)?.readMessage(m.data);
      if (decoded === undefined || decoded === null) throw new Error("nothing decoded");
      if (valuesFile !== null && valueTypes.has(topic.type)) {
        values.push(`{"topic":${JSON.stringify(channel.topic)},"publish":${m.publishTime},` +
                    `"message":${JSON.stringify(decoded, (k, v) => typeof v === "bigint" ? Number(v) : v)}}`);
      }
    } catch (e) {
      if (topic.decode_errors++ === 0) errors.push(`${channel.topic}: message does not decode: ${e.message}`);
    }
  }
  for (const [id, channel] of reader.channelsById) {
    const topic = result.topics[channel.topic];
    topic.payload_sha256 = digests.get(id)?.digest("hex") ?? "";
    if (topic.count > 1) {
      topic.rate_hz = Number(((topic.count - 1) / (Number(last.get(id) - first.get(id)) / 1e9)).toFixed(3));
    }
    const stat = Number(stats.channelMessageCounts.get(id) ?? 0n);
    if (stat !== (indexedCounts.get(id) ?? 0)) {
      errors.push(`${channel.topic}: Statistics says ${stat} messages, the indexed reading found ${indexedCounts.get(id) ?? 0}`);
    }
  }

  if (timesFile !== null) {
    // BigInt nanoseconds do not fit a JSON number's double: written as integer literals.
    const lines = [];
    for (const [id, channel] of reader.channelsById) {
      const t = times.get(id) ?? { publish: [], log: [] };
      lines.push(`{"topic":${JSON.stringify(channel.topic)},"publish":[${t.publish.join(",")}],` +
                 `"log":[${t.log.join(",")}]}`);
    }
    fs.writeFileSync(timesFile, lines.join("\n") + "\n");
  }

  if (valuesFile !== null) fs.writeFileSync(valuesFile, values.join("\n") + "\n");

  // Streamed, with CRC validation, to the footer.
  const stream = new McapStreamReader({ validateCrcs: true });
  const streamCounts = new Map();
  let records = 0;
  let footer = false;
  for (let at = 0; at < fileSize; at += kPiece) {
    stream.append(readAt(at, Math.min(kPiece, fileSize - at)));
    for (let r; (r = stream.nextRecord()); ) {
      records++;
      if (r.type === "Message") streamCounts.set(r.channelId, (streamCounts.get(r.channelId) ?? 0) + 1);
      if (r.type === "Footer") footer = true;
    }
  }
  if (!stream.done() || !footer) errors.push("the streamed reading did not reach the footer");
  for (const [id, channel] of reader.channelsById) {
    if ((streamCounts.get(id) ?? 0) !== (indexedCounts.get(id) ?? 0)) {
      errors.push(`${channel.topic}: streamed ${streamCounts.get(id) ?? 0} messages, indexed ${indexedCounts.get(id) ?? 0}`);
    }
  }
  result.stream_records = records;

  // rosbag2's metadata.
  let metadata = null;
  for await (const m of reader.readMetadata({ name: "rosbag2" })) metadata = m.metadata.get("serialized_metadata");
  if (metadata === null) {
    if (!foreign) errors.push("no rosbag2 metadata record");
  } else if (!foreign) {
    if (!/^  version: 8$/m.test(metadata)) errors.push("rosbag2 metadata: not version 8");
    if (!/^  storage_identifier: mcap$/m.test(metadata)) errors.push("rosbag2 metadata: storage is not mcap");
    const count = /^  message_count: (\d+)$/m.exec(metadata);
    if (!count || Number(count[1]) !== result.messages) {
      errors.push(`rosbag2 metadata: message_count ${count?.[1]}, Statistics ${result.messages}`);
    }
  }
  for (const { topic, min } of expect) {
    const count = result.topics[topic]?.count ?? 0;
    if (count < min) errors.push(`${topic}: ${count} messages, expected at least ${min}`);
  }
} catch (e) {
  errors.push(`${e.message}`);
}
console.log(JSON.stringify(result, null, 2));
process.exit(errors.length === 0 ? 0 : 1);
