// SPDX-License-Identifier: BSD-3-Clause
// The independent side of the MAVLink interop test (tests/mavlink/interop/interop_test.cpp,
// docs/mavlink.md): node-mavlink 2.3.0 and mavlink-mappings, pinned in package-lock.json.
//
//   node interop.mjs decode FRAMES.bin [KEY_HEX]
//     splits and decodes a file of MAVLink frames with node-mavlink and prints, as JSON,
//     every frame's header, checksum, signature (and whether it matches KEY_HEX) and every
//     field of its message by its MAVLink name, plus the splitter's counters.
//   node interop.mjs encode MESSAGES.json OUT.bin
//     encodes the frames described in MESSAGES.json with node-mavlink (MavLinkProtocolV2,
//     signed ones with MavLinkPacketSignature) and writes them one after the other.
//
// Values in JSON: integers of up to 32 bits and finite floats are numbers; 64-bit integers
// are decimal strings (they do not fit a double); "NaN", "Infinity", "-Infinity" and "-0"
// stand for those floats (JSON has no such numbers).
import { createRequire } from 'node:module';
import { readFileSync, writeFileSync } from 'node:fs';
import { Readable } from 'node:stream';

const require = createRequire(import.meta.url);
const mavlink = require('node-mavlink');
const {
  MavLinkPacketSplitter, MavLinkPacketParser, MavLinkProtocolV2, MavLinkPacketSignature,
  minimal, common,
} = mavlink;

const REGISTRY = { ...minimal.REGISTRY, ...common.REGISTRY };

function isWide(type) { return type.startsWith('int64_t') || type.startsWith('uint64_t'); }
function isFloat(type) { return type.startsWith('float') || type.startsWith('double'); }

function toJson(value, type) {
  if (Array.isArray(value)) return value.map((v) => toJson(v, type));
  if (typeof value === 'bigint') return value.toString();
  if (isFloat(type)) {
    if (Number.isNaN(value)) return 'NaN';
    if (value === Infinity) return 'Infinity';
    if (value === -Infinity) return '-Infinity';
    if (Object.is(value, -0)) return '-0';
  }
  return value;
}

function fromJson(value, type) {
  if (Array.isArray(value)) return value.map((v) => fromJson(v, type));
  if (isWide(type)) return BigInt(value);
  if (typeof value === 'string') {
    if (value === 'NaN') return NaN;
    if (value === 'Infinity') return Infinity;
    if (value === '-Infinity') return -Infinity;
    if (value === '-0') return -0;
    throw new Error(`bad value ${value} for ${type}`);
  }
  return value;
}

async function decode(file, keyHex) {
  const key = keyHex ? Buffer.from(keyHex, 'hex') : null;
  const splitter = new MavLinkPacketSplitter();
  const packets = Readable.from([readFileSync(file)]).pipe(splitter).pipe(new MavLinkPacketParser());
  const frames = [];
  for await (const packet of packets) {
    const clazz = REGISTRY[packet.header.msgid];
    const frame = {
      msgid: packet.header.msgid,
      name: clazz ? clazz.MSG_NAME : null,
      payload_length: packet.header.payloadLength,
      incompat_flags: packet.header.incompatibilityFlags,
      compat_flags: packet.header.compatibilityFlags,
      seq: packet.header.seq,
      sysid: packet.header.sysid,
      compid: packet.header.compid,
      crc: packet.crc,
      signature: null,
      fields: {},
    };
    if (packet.signature) {
      frame.signature = {
        link_id: packet.signature.linkId,
        timestamp: packet.signature.timestamp,
        value: packet.signature.signature,
        matches: key ? packet.signature.matches(key) : null,
      };
    }
    if (clazz) {
      const data = packet.protocol.data(packet.payload, clazz);
      for (const field of clazz.FIELDS) frame.fields[field.source] = toJson(data[field.name], field.type);
    }
    frames.push(frame);
  }
  const counters = {
    valid: splitter.validPackages,
    invalid: splitter.invalidPackages,
    unknown: splitter.unknownPackagesCount,
  };
  process.stdout.write(JSON.stringify({ frames, counters }) + '\n');
}

function encode(jsonFile, outFile) {
  const spec = JSON.parse(readFileSync(jsonFile, 'utf8'));
  const key = spec.key ? Buffer.from(spec.key, 'hex') : null;
  const buffers = [];
  for (const f of spec.frames) {
    const clazz = REGISTRY[f.msgid];
    if (!clazz) throw new Error(`message ${f.msgid} not in node-mavlink's registry`);
    const message = new clazz();
    for (const field of clazz.FIELDS) {
      if (!(field.source in f.fields)) throw new Error(`${clazz.MSG_NAME}: no ${field.source}`);
      message[field.name] = fromJson(f.fields[field.source], field.type);
    }
    const flags = f.signed ? MavLinkProtocolV2.IFLAG_SIGNED : 0;
    const protocol = new MavLinkProtocolV2(f.sysid, f.compid, flags);
    let buffer = protocol.serialize(message, f.seq);
    if (f.signed) {
      if (f.timestamp_ms !== undefined) {
        // node-mavlink's own signing path: a Unix time in milliseconds.
        buffer = protocol.sign(buffer, f.link_id, key, f.timestamp_ms);
      } else {
        // An exact timestamp in 10 us units, signed by MavLinkPacketSignature.
        buffer = Buffer.concat([buffer, Buffer.alloc(MavLinkPacketSignature.SIGNATURE_LENGTH)]);
        const signer = new MavLinkPacketSignature(buffer);
        signer.linkId = f.link_id;
        signer.timestamp = f.timestamp;
        signer.signature = signer.calculate(key);
      }
    }
    buffers.push(buffer);
  }
  writeFileSync(outFile, Buffer.concat(buffers));
}

const [command, ...args] = process.argv.slice(2);
if (command === 'decode' && (args.length === 1 || args.length === 2)) {
  await decode(args[0], args[1]);
} else if (command === 'encode' && args.length === 2) {
  encode(args[0], args[1]);
} else {
  process.stderr.write('usage: node interop.mjs decode FRAMES.bin [KEY_HEX] | encode MESSAGES.json OUT.bin\n');
  process.exit(2);
}
