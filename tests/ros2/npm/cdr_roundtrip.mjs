// Every message type through our DDS layer and npm's @foxglove/rosmsg2-serialization (the decoder
// Lichtblick uses), both ways (issue 35). Run by CTest (tests/ros2/cdr_roundtrip.cmake):
//
//   node cdr_roundtrip.mjs --tool <cdr_roundtrip> --source <repository> [--self-test]
//
// For every type the tool registers (`cdr_roundtrip --list`): the ros2msg schema is built here
// from the .msg files (ros2/autodrive_msgs/msg, tests/ros2/upstream/<pkg>/msg), as rosbag2 writes
// it (the type's text, then each dependency after a line of 80 '=' and "MSG: pkg/Type"), and
// parsed with @foxglove/rosmsg; a sample with every field set (non-empty strings, 2-3 element
// sequences, sequences of nested messages, fixed arrays full, bounds respected, values not zero)
// is written with MessageWriter. The tool injects those bytes raw with dds_writecdr, reads them
// with our typed reader, writes the sample back with our typed writer and returns the bytes it
// took raw; MessageReader must decode them to exactly the values written (float32 after
// Math.fround, everything else exact). Also reported: whether the returned payload equals the
// JS writer's bytes. Exit status 1 on any mismatch.
//
// --self-test: the tool changes one value in every sample it read (--mutate); every type must
// then show a mismatch, else the check could not see one and fails.

import { spawnSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";

import rosmsg from "@foxglove/rosmsg";
import serialization from "@foxglove/rosmsg2-serialization";

const { parse } = rosmsg;
const { MessageReader, MessageWriter } = serialization;

function usage(message) {
  console.error(`cdr_roundtrip.mjs: ${message}`);
  console.error(
    "usage: node cdr_roundtrip.mjs --tool <cdr_roundtrip> --source <repo> [--self-test]");
  process.exit(2);
}

const options = { tool: "", source: "", selfTest: false };
for (let i = 2; i < process.argv.length; i++) {
  const arg = process.argv[i];
  if (arg === "--tool" || arg === "--source") {
    if (i + 1 >= process.argv.length) usage(`${arg} needs a value`);
    options[arg.slice(2)] = process.argv[++i];
  } else if (arg === "--self-test") {
    options.selfTest = true;
  } else {
    usage(`unknown argument ${arg}`);
  }
}
if (!options.tool || !options.source) usage("--tool and --source are required");

// ---- Schemas from the .msg files -------------------------------------------------------------

const PRIMITIVES = new Set([
  "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
  "uint32", "int64", "uint64", "string", "wstring",
]);

// "pkg/Type" -> path of its .msg.
function findMsgFiles(source) {
  const files = new Map();
  const add = (pkg, dir) => {
    if (!fs.existsSync(dir)) return;
    for (const name of fs.readdirSync(dir)) {
      if (name.endsWith(".msg")) files.set(`${pkg}/${name.slice(0, -4)}`, path.join(dir, name));
    }
  };
  add("autodrive_msgs", path.join(source, "ros2/autodrive_msgs/msg"));
  const upstream = path.join(source, "tests/ros2/upstream");
  for (const pkg of fs.readdirSync(upstream)) add(pkg, path.join(upstream, pkg, "msg"));
  return files;
}

// The "pkg/Type" names of the complex fields of the .msg text `text` of package `pkg`.
function dependenciesOf(text, pkg) {
  const deps = [];
  for (const raw of text.split("\n")) {
    const line = raw.replace(/#.*/, "").trim();
    if (line === "") continue;
    let type = line.split(/\s+/)[0];
    if (/^\S+\s+[A-Z][A-Z0-9_]*\s*=/.test(line)) continue;  // a constant
    type = type.replace(/\[.*\]$/, "").replace(/<=\d+$/, "");
    if (PRIMITIVES.has(type)) continue;
    const parts = type.split("/");
    const full =
      parts.length === 1 ? `${pkg}/${type}` : parts.length === 2 ? type : `${parts[0]}/${parts[2]}`;
    deps.push(full);
  }
  return deps;
}

// The rosbag2-style ros2msg schema of "pkg/Type".
function schemaText(files, type) {
  const read = (t) => {
    const file = files.get(t);
    if (file === undefined) throw new Error(`no .msg for ${t}`);
    return fs.readFileSync(file, "utf8");
  };
  const own = read(type);
  const order = [];
  const seen = new Set([type]);
  const visit = (t, text) => {
    for (const dep of dependenciesOf(text, t.split("/")[0])) {
      if (seen.has(dep)) continue;
      seen.add(dep);
      order.push(dep);
      visit(dep, read(dep));
    }
  };
  visit(type, own);
  let schema = own;
  for (const dep of order) {
    if (!schema.endsWith("\n")) schema += "\n";
    schema += `${"=".repeat(80)}\nMSG: ${dep}\n${read(dep)}`;
  }
  return schema;
}

// ---- Samples with every field set ------------------------------------------------------------

// Deterministic values, different from field to field, none zero.
class Values {
  n = 0;
  next() {
    return ++this.n;
  }
  primitive(type, bound) {
    const n = this.next();
    switch (type) {
      case "bool":
        return n % 3 !== 0;
      case "int8":
        return -((n * 7) % 120) - 1;
      case "uint8":
        return 128 + ((n * 37) % 127);
      case "int16":
        return -(1000 + ((n * 311) % 30000));
      case "uint16":
        return 0xa000 + ((n * 257) % 0x5fff);
      case "int32":
        return -(0x1234567 + n * 7919);
      case "uint32":
        return (0x89abcdef + n * 0x01010101) >>> 0;
      case "int64":
        return -(0x123456789abcdn + BigInt(n) * 7919n);
      case "uint64":
        return 0xfedcba9876543210n + BigInt(n) * 65537n;
      case "float32":
        return Math.fround((n % 2 === 0 ? -1 : 1) * (1.375 + n * 0.3141592));
      case "float64":
        return (n % 2 === 0 ? -1 : 1) * (0.1 + n * 1.0000001234567);
      case "string": {
        const s = `s${n}-${"abcdefghijklmnopqrstuvwxyz".slice(0, 1 + (n % 26))}`;
        return bound !== undefined ? s.slice(0, Math.max(1, bound)) : s;
      }
      case "time":
        return { sec: 1700000000 + n, nanosec: 123456789 + n };
      case "duration":
        return { sec: -(5 + n), nanosec: 987654321 - n };
      default:
        throw new Error(`unsupported primitive ${type}`);
    }
  }
}

function definitionMap(definitions) {
  return new Map(definitions.map((d) => [d.name ?? "", d.definitions]));
}

function rootOf(definitions) {
  return definitions.find((d) => !d.definitions.every((f) => f.isConstant === true)) ??
    definitions[0];
}

function makeSample(fields, defs, values) {
  const sample = {};
  for (const field of fields) {
    if (field.isConstant === true) continue;
    const one = () =>
      field.isComplex === true
        ? makeSample(defs.get(field.type), defs, values)
        : values.primitive(field.type, field.upperBound);
    if (field.isArray === true) {
      let length = field.arrayLength;
      if (length === undefined) {
        length = 2 + (values.next() % 2);  // 2 or 3
        if (field.arrayUpperBound !== undefined) length = Math.min(length, field.arrayUpperBound);
      }
      sample[field.name] = Array.from({ length }, one);
    } else {
      sample[field.name] = one();
    }
  }
  return sample;
}

// ---- Comparison ------------------------------------------------------------------------------

function show(v) {
  if (typeof v === "bigint") return `${v}n`;
  if (typeof v === "string") return JSON.stringify(v);
  if (v !== null && typeof v === "object") {
    return JSON.stringify(v, (_k, x) => (typeof x === "bigint" ? `${x}n` : x));
  }
  return String(v);
}

function comparePrimitive(type, expected, actual, where) {
  if (type === "time" || type === "duration") {
    if (actual === null || typeof actual !== "object" || actual.sec !== expected.sec ||
        actual.nanosec !== expected.nanosec) {
      return `${where}: expected ${show(expected)}, got ${show(actual)}`;
    }
    return null;
  }
  const same = type === "float32"
    ? typeof actual === "number" && Math.fround(expected) === Math.fround(actual)
    : actual === expected;
  return same ? null : `${where}: expected ${show(expected)}, got ${show(actual)}`;
}

// The first difference between `expected` and `actual` as "path: expected X, got Y", or null.
function compare(fields, defs, expected, actual, where) {
  if (actual === null || typeof actual !== "object") {
    return `${where || "."}: not a message: ${show(actual)}`;
  }
  for (const field of fields) {
    if (field.isConstant === true) continue;
    const at = where ? `${where}.${field.name}` : field.name;
    const e = expected[field.name];
    let a = actual[field.name];
    const one = (ev, av, p) =>
      field.isComplex === true
        ? compare(defs.get(field.type), defs, ev, av, p)
        : comparePrimitive(field.type, ev, av, p);
    if (field.isArray === true) {
      if (ArrayBuffer.isView(a)) a = Array.from(a);
      if (!Array.isArray(a)) return `${at}: expected an array, got ${show(a)}`;
      if (a.length !== e.length) return `${at}: expected ${e.length} elements, got ${a.length}`;
      for (let i = 0; i < e.length; i++) {
        const d = one(e[i], a[i], `${at}[${i}]`);
        if (d !== null) return d;
      }
    } else {
      const d = one(e, a, at);
      if (d !== null) return d;
    }
  }
  return null;
}

// ---- The round trip --------------------------------------------------------------------------

// Runs the tool; its standard output when `capture`, else the tool's log goes to ours.
function runTool(args, capture) {
  const result = spawnSync(options.tool, args, {
    encoding: "utf8",
    stdio: ["ignore", capture ? "pipe" : "inherit", "inherit"],
    timeout: 240_000,
  });
  if (result.error) throw new Error(`${options.tool}: ${result.error.message}`);
  if (result.status !== 0) {
    throw new Error(`${options.tool} ${args.join(" ")} exited ${result.status}`);
  }
  return result.stdout;
}

function toHex(bytes) {
  return Buffer.from(bytes.buffer, bytes.byteOffset, bytes.byteLength).toString("hex");
}

// How the returned bytes relate to the JS writer's (payloads after the 4-byte header). Cyclone
// pads a payload to a multiple of 4 bytes with zeros and declares the padding in the last two
// bits of the encapsulation options (XCDR's rule); MessageWriter does not pad.
function compareBytes(written, returned) {
  const a = written.subarray(4);
  const b = returned.subarray(4);
  const common = Math.min(a.length, b.length);
  for (let i = 0; i < common; i++) {
    if (a[i] !== b[i]) return { identical: false, text: `payload differs at byte ${i}` };
  }
  if (a.length === b.length) return { identical: true, text: "payload bytes identical" };
  const tail = b.length > a.length ? b.subarray(a.length) : a.subarray(b.length);
  const declared = returned.length >= 4 ? returned[3] & 3 : -1;
  const padding = b.length > a.length && tail.every((x) => x === 0) && declared === tail.length;
  return {
    identical: false,
    text: padding
      ? `payload bytes identical, then ${tail.length} zero padding bytes declared in the options`
      : `payload ${b.length} bytes for the writer's ${a.length}`,
    padding,
  };
}

const files = findMsgFiles(options.source);
const types = runTool(["--list"], true).split("\n").filter((l) => l !== "");
let failures = 0;

// Every autodrive_msgs .msg must be a registered type.
for (const key of files.keys()) {
  if (key.startsWith("autodrive_msgs/") && !types.includes(key.replace("/", "/msg/"))) {
    console.log(`MISSING ${key}: a .msg the tool does not register`);
    failures++;
  }
}

const cases = [];
for (const type of types) {
  const [pkg, , name] = type.split("/");
  try {
    const definitions = parse(schemaText(files, `${pkg}/${name}`), { ros2: true });
    const defs = definitionMap(definitions);
    const root = rootOf(definitions).definitions;
    const sample = makeSample(root, defs, new Values());
    const bytes = new MessageWriter(definitions).writeMessage(sample);
    // The JS library agrees with itself, or nothing below means anything.
    const self = compare(root, defs, sample, new MessageReader(definitions).readMessage(bytes), "");
    if (self !== null) throw new Error(`MessageWriter/MessageReader disagree: ${self}`);
    cases.push({ type, definitions, defs, root, sample, bytes });
  } catch (e) {
    console.log(`ERROR ${type}: ${e.message}`);
    failures++;
  }
}

const work = fs.mkdtempSync(path.join(os.tmpdir(), "cdr_roundtrip-"));
let outputLines;
try {
  const input = path.join(work, "in.txt");
  const output = path.join(work, "out.txt");
  fs.writeFileSync(input, cases.map((c) => `${c.type} ${toHex(c.bytes)}\n`).join(""));
  runTool(["--input", input, "--output", output, ...(options.selfTest ? ["--mutate"] : [])], false);
  outputLines = fs.readFileSync(output, "utf8").split("\n").filter((l) => l !== "");
} finally {
  fs.rmSync(work, { recursive: true, force: true });
}

let mismatches = 0;
let identical = 0;
let padded = 0;
let detected = 0;
if (outputLines.length !== cases.length) {
  console.log(`ERROR the tool returned ${outputLines.length} samples for ${cases.length}`);
  failures++;
}
cases.forEach((c, i) => {
  const line = outputLines[i] ?? "";
  const space = line.indexOf(" ");
  const type = line.slice(0, space);
  const rest = line.slice(space + 1);
  if (type !== c.type) {
    console.log(`ERROR ${c.type}: the tool answered for ${show(type)}`);
    failures++;
    return;
  }
  if (rest.startsWith("ERROR")) {
    console.log(`ERROR ${c.type}: ${rest.slice(6)}`);
    failures++;
    return;
  }
  const returned = new Uint8Array(Buffer.from(rest, "hex"));
  const bytes = compareBytes(c.bytes, returned);
  if (bytes.identical) identical++;
  if (bytes.padding) padded++;
  let difference;
  try {
    const decoded = new MessageReader(c.definitions).readMessage(returned);
    difference = compare(c.root, c.defs, c.sample, decoded, "");
  } catch (e) {
    difference = `MessageReader failed: ${e.message}`;
  }
  if (difference === null) {
    console.log(`OK ${c.type} (${c.bytes.length} bytes written; ${bytes.text})`);
  } else {
    mismatches++;
    detected++;
    console.log(`MISMATCH ${c.type}: ${difference} (${bytes.text})`);
  }
});

console.log(`${cases.length} types, ${mismatches} mismatches, ${failures} errors; ` +
  `payload bytes identical for ${identical} of ${cases.length}, and for ${padded} more but for ` +
  "Cyclone's declared padding to a 4-byte multiple");
if (options.selfTest) {
  const ok = failures === 0 && cases.length > 0 && detected === cases.length;
  console.log(`self-test: --mutate made ${detected} of ${cases.length} types mismatch: ` +
    (ok ? "the check sees a changed value in every type" : "FAILED"));
  process.exit(ok ? 0 : 1);
}
process.exit(failures === 0 && mismatches === 0 && cases.length > 0 ? 0 : 1);
