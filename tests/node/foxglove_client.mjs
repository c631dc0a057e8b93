// Foxglove's own WebSocket client (@foxglove/ws-protocol's FoxgloveClient over the `ws`
// package) against hapticloth-server --foxglove; tests/python/test_foxglove.py runs it.
//
//   node foxglove_client.mjs ws://127.0.0.1:PORT cloth      one SceneUpdate from /cloth, decoded
//                                                          with the schema the server advertised
//   node foxglove_client.mjs ws://127.0.0.1:PORT churn N    N clients connect, see the channels,
//                                                          and drop, one after another
//   node foxglove_client.mjs ws://127.0.0.1:PORT subscribe S   every channel for S seconds:
//                                                          messages per topic (hapticloth-bench
//                                                          haptic --foxglove-clients)
//
// Prints one JSON object; exits 1 with {"error": ...} if anything does not arrive in time.
import wsProtocol from "@foxglove/ws-protocol";  // CommonJS: named exports through the default
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;

// The classic protocol (FoxgloveClient's) and the SDK's name for it with inline schemas; the
// server picks the one it speaks.
const SUBPROTOCOLS = [FoxgloveClient.SUPPORTED_SUBPROTOCOL, "foxglove.sdk.v1"];
const TIMEOUT_MS = 15000;

function connect(url) {
  const ws = new WebSocket(url, SUBPROTOCOLS);
  return { ws, client: new FoxgloveClient({ ws }) };
}

function withTimeout(promise, what) {
  let timer;
  return Promise.race([
    promise,
    new Promise((_, reject) => {
      timer = setTimeout(() => reject(new Error(`no ${what} within ${TIMEOUT_MS} ms`)), TIMEOUT_MS);
    }),
  ]).finally(() => clearTimeout(timer));
}

// The channels of the first advertisement, by topic (rejected at once if the connection fails).
function advertised(client) {
  return new Promise((resolve, reject) => {
    client.on("advertise", (chs) => resolve(new Map(chs.map((c) => [c.topic, c]))));
    client.on("error", (e) => reject(new Error(`connection: ${e.message || e}`)));
  });
}

async function cloth(url) {
  const { ws, client } = connect(url);
  const channels = await withTimeout(advertised(client), "channel advertisement");
  const ch = channels.get("/cloth");
  if (!ch) throw new Error(`no /cloth among ${[...channels.keys()].join(", ")}`);
  const fds = descriptor.FileDescriptorSet.decode(Buffer.from(ch.schema, "base64"));
  const type = protobuf.Root.fromDescriptor(fds).lookupType(ch.schemaName);
  const first = new Promise((resolve) => client.on("message", (m) => resolve(m)));
  client.subscribe(ch.id);
  const msg = await withTimeout(first, "/cloth message");
  const update = type.toObject(type.decode(new Uint8Array(msg.data.buffer, msg.data.byteOffset, msg.data.byteLength)));
  const mesh = update.entities[0].triangles[0];
  client.close();
  return {
    subprotocol: ws.protocol,
    topics: [...channels.keys()].sort(),
    schemas: Object.fromEntries([...channels.values()].map((c) => [c.topic, [c.encoding, c.schemaName, c.schemaEncoding]])),
    entity: update.entities[0].id,
    frame_id: update.entities[0].frameId,
    vertices: mesh.points.length,
    colors: mesh.colors.length,
    triangles: mesh.indices.length / 3,
  };
}

async function churn(url, n) {
  let seen = 0;
  for (let i = 0; i < n; i++) {
    const { client } = connect(url);
    const channels = await withTimeout(advertised(client), `advertisement (client ${i + 1})`);
    if (channels.has("/cloth")) seen++;
    client.close();
  }
  return { clients: n, saw_cloth: seen };
}

async function subscribeAll(url, seconds) {
  const { client } = connect(url);
  const channels = await withTimeout(advertised(client), "channel advertisement");
  const topicOf = new Map();
  for (const ch of channels.values()) topicOf.set(client.subscribe(ch.id), ch.topic);
  const counts = Object.fromEntries([...channels.keys()].map((t) => [t, 0]));
  client.on("message", (m) => counts[topicOf.get(m.subscriptionId)]++);
  console.log("ready");
  await new Promise((resolve) => setTimeout(resolve, seconds * 1000));
  client.close();
  return { messages: counts };
}

const [url, mode, count] = process.argv.slice(2);
try {
  const out = mode === "churn" ? await churn(url, Number(count))
    : mode === "subscribe" ? await subscribeAll(url, Number(count))
    : await cloth(url);
  console.log(JSON.stringify(out));
  process.exit(0);
} catch (e) {
  console.log(JSON.stringify({ error: String(e.message || e) }));
  process.exit(1);
}
