// Foxglove's reference client (@foxglove/ws-protocol) driving a server's playback as the app's timeline does:
// it subscribes to /clock, asks to play at `speed`, and once `before` clock messages came, seeks back to
// `seekSeconds` (of the recording's sim time) and takes `after` more. The reference client has no playback
// messages yet, so the two binary frames of foxglove-sdk's protocol are written and read here: a
// PlaybackControlRequest (opcode 3: command u8, speed f32, had_seek u8, seek_time u64, id length u32, id) and a
// PlaybackState (opcode 5: status u8, current_time u64, speed f32, did_seek u8, id length u32, id), all little-endian.
// Prints one line of JSON: the /clock messages (CDR, base64) before and after the seek, the playback states heard.
//
//   node foxglove_playback.js ws://127.0.0.1:8765 2.0 5 1.5 5
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { WebSocket } = require("ws");

const [url, speedText, beforeText, seekText, afterText] = process.argv.slice(2);
const speed = Number(speedText), before = Number(beforeText), after = Number(afterText);
const seekNs = BigInt(Math.round(Number(seekText) * 1e9));
const seen = { serverInfo: null, before: [], after: [], states: [], errors: [] };
let phase = "before";

const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });

function request(command, seek, id) {
  const idBytes = new TextEncoder().encode(id);
  const frame = Buffer.alloc(1 + 1 + 4 + 1 + 8 + 4 + idBytes.length);
  let at = frame.writeUInt8(3, 0);
  at = frame.writeUInt8(command, at);
  at = frame.writeFloatLE(speed, at);
  at = frame.writeUInt8(seek === null ? 0 : 1, at);
  at = frame.writeBigUInt64LE(seek === null ? 0n : seek, at);
  at = frame.writeUInt32LE(idBytes.length, at);
  Buffer.from(idBytes).copy(frame, at);
  ws.send(frame);
}

function finish(code) {
  process.stdout.write(JSON.stringify(seen) + "\n");
  client.close();
  process.exit(code);
}

setTimeout(() => finish(1), 30000);
ws.on("message", (raw, isBinary) => {
  const data = Buffer.from(raw); // the reference client asks the socket for ArrayBuffers
  if (!isBinary || data[0] !== 5) {
    return;
  }
  const idLength = data.readUInt32LE(15);
  seen.states.push({
    status: data.readUInt8(1),
    currentTime: data.readBigUInt64LE(2).toString(),
    speed: data.readFloatLE(10),
    didSeek: data.readUInt8(14) === 1,
    requestId: data.subarray(19, 19 + idLength).toString(),
  });
});
client.on("serverInfo", (info) => {
  seen.serverInfo = { name: info.name, capabilities: info.capabilities };
});
client.on("advertise", (channels) => {
  const clock = channels.find((c) => c.topic === "/clock");
  if (clock) {
    client.subscribe(clock.id);
    request(0, null, "play");
  }
});
client.on("message", (event) => {
  const bytes = Buffer.from(event.data.buffer, event.data.byteOffset, event.data.byteLength);
  const stamp = bytes.toString("base64"); // a rosgraph_msgs/msg/Clock in CDR, for the test to decode
  if (phase === "before") {
    seen.before.push(stamp);
    if (seen.before.length >= before) {
      phase = "seeking";
      request(0, seekNs, "seek-back");
    }
  } else if (phase === "seeking") {
    if (seen.states.some((s) => s.requestId === "seek-back")) {
      phase = "after";
      seen.after.push(stamp);
    }
  } else if (seen.after.length < after) {
    seen.after.push(stamp);
    if (seen.after.length >= after) {
      finish(0);
    }
  }
});
client.on("error", (error) => {
  if (!String(error).includes("opcode")) {
    seen.errors.push(String(error)); // the reference client knows no PlaybackState opcode: read above instead
  }
});
