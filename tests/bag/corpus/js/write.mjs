// Re-writes an MCAP file (INPUT, read with @mcap/core's stream reader) with @mcap/core's McapWriter.
// Usage: node write.mjs INPUT OUTPUT '{"useChunks": true, "chunkSize": 65536, "compression": "zstd", ...}'
// Options are McapWriterOptions' booleans and chunkSize; "compression" is "", "zstd" or "lz4".
import { closeSync, openSync, readFileSync, writeSync } from "node:fs";

import zstd from "@foxglove/wasm-zstd";
import { McapStreamReader, McapWriter } from "@mcap/core";
import lz4 from "lz4js";

const [input, output, optionsText] = process.argv.slice(2);
const { compression = "", ...options } = JSON.parse(optionsText ?? "{}");
await zstd.isLoaded;

class FileWritable {
  constructor(path) {
    this.fd = openSync(path, "w");
    this.offset = 0n;
  }
  async write(buffer) {
    writeSync(this.fd, buffer);
    this.offset += BigInt(buffer.byteLength);
  }
  position() {
    return this.offset;
  }
}

const compressors = {
  "": undefined,
  zstd: (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) }),
  lz4: (data) => ({ compression: "lz4", compressedData: lz4.compress(data) }),
};
if (!(compression in compressors)) {
  throw new Error(`unknown compression ${compression}`);
}
const writable = new FileWritable(output);
const writer = new McapWriter({ ...options, writable, compressChunk: compressors[compression] });
const reader = new McapStreamReader({ validateCrcs: true });
reader.append(readFileSync(input));
const schemaIds = new Map();
const channelIds = new Map();
let started = false;
for (let record; (record = reader.nextRecord()); ) {
  if (record.type === "Header") {
    await writer.start({ profile: record.profile, library: "@mcap/core (smm corpus)" });
    started = true;
  } else if (record.type === "Schema") {
    const { id, type, ...schema } = record;
    schemaIds.set(id, await writer.registerSchema(schema));
  } else if (record.type === "Channel") {
    const { id, type, schemaId, ...channel } = record;
    channelIds.set(id, await writer.registerChannel({ ...channel, schemaId: schemaIds.get(schemaId) ?? 0 }));
  } else if (record.type === "Message") {
    const { type, channelId, ...message } = record;
    await writer.addMessage({ ...message, channelId: channelIds.get(channelId) });
  } else if (record.type === "Metadata") {
    const { type, ...metadata } = record;
    await writer.addMetadata(metadata);
  }
}
if (!started) {
  throw new Error(`${input}: no Header record`);
}
await writer.end();
closeSync(writable.fd);
