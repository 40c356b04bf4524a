// Foxglove's reference client for its WebSocket protocol (@foxglove/ws-protocol), as the suite runs it against the
// line's Foxglove server: it subscribes to the topics asked for, takes the number of messages asked of each, then
// calls a service if asked, and prints on one line what it saw as JSON (message bytes in base64). Exit 1 if it
// timed out.
//
//   node foxglove_client.js ws://127.0.0.1:8765 /joint_states:3,/tf_static:1 [/pause '{}']
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { WebSocket } = require("ws");

const [url, topicList, serviceName, serviceArgs] = process.argv.slice(2);
const wanted = new Map(topicList.split(",").filter((t) => t).map((t) => [t.split(":")[0], Number(t.split(":")[1])]));
const topics = [...wanted.keys()];
let called = false;
const seen = { channels: [], services: [], messages: {}, times: [], serviceAnswer: null, serverInfo: null };
const bySubscription = new Map();

// foxglove-sdk's servers (and the app since 2025) speak `foxglove.sdk.v1`: the same protocol as the reference
// client's `foxglove.websocket.v1` under a new name (foxglove/ws-protocol#916 lets the socket choose it)
const protocols = ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL];
const client = new FoxgloveClient({ ws: new WebSocket(url, protocols) });

function enough() {
  return topics.every((t) => (seen.messages[t] || []).length >= wanted.get(t)) && seen.times.length > 0;
}

function finish(code) {
  process.stdout.write(JSON.stringify(seen) + "\n");
  client.close();
  process.exit(code);
}

setTimeout(() => finish(1), 30000);
client.on("serverInfo", (info) => {
  seen.serverInfo = { name: info.name, capabilities: info.capabilities };
});
client.on("advertise", (channels) => {
  for (const c of channels) {
    seen.channels.push({ topic: c.topic, encoding: c.encoding, schemaName: c.schemaName, schemaEncoding: c.schemaEncoding, schema: c.schema });
    if (topics.includes(c.topic)) {
      bySubscription.set(client.subscribe(c.id), c.topic);
    }
  }
});
const serviceIds = new Map();
client.on("advertiseServices", (services) => {
  for (const s of services) {
    seen.services.push(s.name);
    serviceIds.set(s.name, s.id);
  }
});

function callOrFinish() {
  if (!serviceName) {
    finish(0);
  } else if (!called && serviceIds.has(serviceName)) {
    called = true;
    const data = new TextEncoder().encode(serviceArgs || "{}");
    client.sendServiceCallRequest({ serviceId: serviceIds.get(serviceName), callId: 1, encoding: "json", data });
  }
}
client.on("serviceCallResponse", (response) => {
  seen.serviceAnswer = JSON.parse(new TextDecoder().decode(response.data));
  finish(0);
});
client.on("serviceCallFailure", (failure) => {
  seen.serviceAnswer = { failure: failure.message };
  finish(0);
});
client.on("time", (time) => {
  if (seen.times.length < 1000) {
    seen.times.push(time.timestamp.toString());
  }
});
client.on("message", (event) => {
  const topic = bySubscription.get(event.subscriptionId);
  const list = (seen.messages[topic] = seen.messages[topic] || []);
  if (list.length < wanted.get(topic)) {
    list.push({ logTime: event.timestamp.toString(), data: Buffer.from(event.data.buffer, event.data.byteOffset, event.data.byteLength).toString("base64") });
  }
  if (enough()) {
    callOrFinish();
  }
});
client.on("error", (error) => {
  seen.error = String(error);
});
