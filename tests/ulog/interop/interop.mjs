// SPDX-License-Identifier: BSD-3-Clause
// The independent side of the ULog interop test (tests/ulog/interop/interop_test.cpp,
// docs/ulog.md): @foxglove/ulog 2.3.2, pinned in package-lock.json.
//
//   node interop.mjs LOG.ulg
//     reads LOG.ulg with @foxglove/ulog and prints, as JSON: the header (version, timestamp,
//     flag bits), information (by name) and multi-information (by key) of the definitions
//     section, the parameter table, every format definition's fields, every subscription
//     (msg_id, multi_id, topic, message count, first and last timestamp and a SHA-256 over
//     every message's canonical text), the logged strings and the dropouts.
//
// Canonical text of a data message (the C++ side builds the same): its fields in definition
// order, nested types and arrays flattened, fields whose name starts with '_' left out, one
// value per leaf joined by ',', messages joined by '\n'. A leaf value: integers in decimal
// (64-bit ones from BigInt), bool 1/0, a char its code, a char array the hex of its UTF-8
// bytes, float and double the hex of the IEEE-754 double they widen to ("nan" for NaN, so
// that NaN payloads do not matter).
import { createHash } from 'node:crypto';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const { ULog, MessageType } = require('@foxglove/ulog');
const { FileReader } = require('@foxglove/ulog/node');

const f64 = new Float64Array(1);
const u64 = new BigUint64Array(f64.buffer);
function floatHex(v) {
  if (Number.isNaN(v)) return 'nan';
  f64[0] = v;
  return u64[0].toString(16);
}
const hex = (bytes) => Buffer.from(bytes).toString('hex');

function leaf(type, v, out) {
  switch (type) {
    case 'float':
    case 'double':
      out.push(floatHex(v));
      break;
    case 'bool':
      out.push(v ? '1' : '0');
      break;
    case 'char':
      out.push(String(v.charCodeAt(0)));
      break;
    default:
      out.push(v.toString());
  }
}

function flatten(def, defs, value, out) {
  for (const field of def.fields) {
    if (field.name.startsWith('_')) continue;
    const v = value[field.name];
    if (field.isComplex) {
      const nested = defs.get(field.type);
      if (field.arrayLength !== undefined) {
        for (const e of v) flatten(nested, defs, e, out);
      } else {
        flatten(nested, defs, v, out);
      }
    } else if (field.arrayLength !== undefined) {
      if (field.type === 'char') {
        out.push(hex(Buffer.from(v, 'utf8')));
      } else {
        for (const e of v) leaf(field.type, e, out);
      }
    } else {
      leaf(field.type, v, out);
    }
  }
}

function infoValue(v) {
  if (typeof v === 'bigint') return v.toString();
  if (typeof v === 'string') return hex(Buffer.from(v, 'utf8'));
  if (typeof v === 'boolean') return v ? '1' : '0';
  if (typeof v === 'number') return Number.isInteger(v) ? v.toString() : floatHex(v);
  if (Array.isArray(v)) return v.map(infoValue).join(',');
  return String(v);
}

const path = process.argv[2];
const ulog = new ULog(new FileReader(path));
await ulog.open();
const header = ulog.header;
const defs = header.definitions;

const out = {
  version: header.version,
  timestamp: header.timestamp.toString(),
  compat_flags: header.flagBits ? header.flagBits.compatibleFlags : null,
  incompat_flags: header.flagBits ? header.flagBits.incompatibleFlags : null,
  appended_offsets: header.flagBits ? header.flagBits.appendedOffsets.map(String) : null,
  info: {},
  multi_info: {},
  parameters: {},
  formats: {},
  subscriptions: [],
  logs: [],
  dropouts: [],
};
for (const [name, value] of header.information) {
  if (Array.isArray(value) && name.includes(' ')) {
    out.multi_info[name] = value.map(infoValue);  // multi-information: keyed by 'type name'
  } else {
    out.info[name] = infoValue(value);
  }
}
for (const [name, entry] of header.parameters) {
  out.parameters[name] = { value: floatHex(entry.value), default_types: entry.defaultTypes };
}
for (const [name, def] of defs) {
  out.formats[name] = def.fields.map((f) =>
    `${f.type}${f.arrayLength !== undefined ? `[${f.arrayLength}]` : ''} ${f.name}`);
}

// Messages come in timestamp order (ties in file order); per subscription that is its file
// order when its timestamps do not go backwards (the C++ side sorts the same way).
const perSub = new Map();
for (const [id, sub] of ulog.subscriptions) {
  perSub.set(id, { hash: createHash('sha256'), count: 0, first: null, last: null, sub, sep: '' });
}
for await (const msg of ulog.readMessages()) {
  if (msg.type === MessageType.Data) {
    const s = perSub.get(msg.msgId);
    const leaves = [];
    flatten(s.sub, defs, msg.value, leaves);
    s.hash.update(s.sep + leaves.join(','));
    s.sep = '\n';
    const ts = msg.value.timestamp.toString();
    if (s.first === null) s.first = ts;
    s.last = ts;
    s.count += 1;
  } else if (msg.type === MessageType.Log || msg.type === MessageType.LogTagged) {
    out.logs.push({
      level: msg.logLevel,
      tag: msg.type === MessageType.LogTagged ? msg.tag : null,
      timestamp: msg.timestamp.toString(),
      text: hex(Buffer.from(msg.message, 'utf8')),
    });
  } else if (msg.type === MessageType.Dropout) {
    out.dropouts.push(msg.duration);
  }
}
for (const [id, s] of perSub) {
  out.subscriptions.push({
    msg_id: id,
    multi_id: s.sub.multiId,
    name: s.sub.name,
    count: s.count,
    first: s.first,
    last: s.last,
    sha256: s.hash.digest('hex'),
  });
}
out.subscriptions.sort((a, b) => a.msg_id - b.msg_id);
process.stdout.write(JSON.stringify(out));
