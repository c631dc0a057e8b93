//! A C ABI over the Foxglove SDK: one context with a WebSocket server (the live view) and/or an
//! MCAP writer (the recording), and the channels the server and `hapticloth-export` publish:
//!
//! | channel        | schema                       | encoding |
//! |----------------|------------------------------|----------|
//! | `/cloth`       | `foxglove.SceneUpdate`       | protobuf |
//! | `/fingertips`  | `foxglove.SceneUpdate`       | protobuf |
//! | `/haptics`     | `hapticloth.Haptics` (JSON schema from the caller) | json |
//! | `/loop`        | `hapticloth.LoopStats` (JSON schema from the caller) | json |
//! | `/events`      | `foxglove.Log`               | protobuf |
//! | `/tactile`     | `hapticloth.Tactile` (JSON schema from the caller) | json |
//! | `/tactile/pins`| `foxglove.RawImage`          | protobuf |
//!
//! Every message carries its log time (ns since the Unix epoch) from the caller, so a recording
//! and an export of the same run agree. Calls come from one (non-real-time) thread. Errors leave
//! a message for `hz_last_error`, like the zenoh half of this crate.
//!
//! Declared in server/transport/zenoh_bridge/include/foxglove_bridge.h.

use std::ffi::c_char;
use std::fs::{File, OpenOptions};
use std::io::BufWriter;
use std::sync::Arc;

use foxglove::messages::{
    ArrowPrimitive, Color, Log, Point3, Pose, Quaternion, RawImage, SceneEntity, SceneUpdate,
    SpherePrimitive, Timestamp, TriangleListPrimitive, Vector3,
};
use foxglove::{
    Channel, Context, McapWriterHandle, PartialMetadata, RawChannel, Schema, WebSocketServerHandle,
};

use crate::{set_error, str_arg};

/// The JSON channels, numbered as in foxglove_bridge.h.
const JSON_TOPICS: [&str; 3] = ["/haptics", "/loop", "/tactile"];

pub struct HfSink {
    // Channels first: they are closed before the sinks go.
    cloth: Channel<SceneUpdate>,
    fingertips: Channel<SceneUpdate>,
    events: Channel<Log>,
    pins: Channel<RawImage>,
    json: Vec<Option<Arc<RawChannel>>>,
    frame: String,
    mcap: Option<McapWriterHandle<BufWriter<File>>>,
    ws: Option<WebSocketServerHandle>,
    ctx: Arc<Context>,
}

fn meta(log_time_ns: u64) -> PartialMetadata {
    PartialMetadata { log_time: Some(log_time_ns) }
}

fn stamp(log_time_ns: u64) -> Option<Timestamp> {
    Some(Timestamp::new((log_time_ns / 1_000_000_000) as u32, (log_time_ns % 1_000_000_000) as u32))
}

fn slice<'a, T>(p: *const T, n: usize) -> &'a [T] {
    if n == 0 || p.is_null() {
        &[]
    } else {
        // SAFETY: the caller passes `n` valid elements that outlive the call.
        unsafe { std::slice::from_raw_parts(p, n) }
    }
}

fn sink<'a>(s: *mut HfSink) -> Option<&'a mut HfSink> {
    // SAFETY: a handle from hf_open, used from one thread.
    unsafe { s.as_mut() }
}

/// Opens a context with a WebSocket server on `ws_host:ws_port` (ws_host NULL: none; port 0:
/// any free one) and an MCAP writer on a new file `mcap_path` (NULL: none; an existing file is
/// an error, never overwritten). `frame` names the scene frame of every entity. NULL on failure.
#[no_mangle]
pub extern "C" fn hf_open(
    ws_host: *const c_char,
    ws_port: u16,
    mcap_path: *const c_char,
    server_name: *const c_char,
    frame: *const c_char,
) -> *mut HfSink {
    let Some(name) = str_arg(server_name, "server name") else { return std::ptr::null_mut() };
    let Some(frame) = str_arg(frame, "frame") else { return std::ptr::null_mut() };
    let ctx = Context::new();
    let cloth = ctx.channel_builder("/cloth").build::<SceneUpdate>();
    let fingertips = ctx.channel_builder("/fingertips").build::<SceneUpdate>();
    let events = ctx.channel_builder("/events").build::<Log>();
    let pins = ctx.channel_builder("/tactile/pins").build::<RawImage>();
    let mut mcap = None;
    if !mcap_path.is_null() {
        let Some(path) = str_arg(mcap_path, "mcap path") else { return std::ptr::null_mut() };
        let file = match OpenOptions::new().write(true).create_new(true).open(path) {
            Ok(f) => f,
            Err(e) => {
                set_error(format!("{path}: {e}"));
                return std::ptr::null_mut();
            }
        };
        // The SDK's defaults: zstd-compressed chunks, each written whole, so a file cut short
        // reads back up to its last finished chunk.
        match ctx.mcap_writer().create(BufWriter::new(file)) {
            Ok(w) => mcap = Some(w),
            Err(e) => {
                set_error(format!("{path}: {e}"));
                return std::ptr::null_mut();
            }
        }
    }
    let mut ws = None;
    if !ws_host.is_null() {
        let Some(host) = str_arg(ws_host, "host") else { return std::ptr::null_mut() };
        match ctx.websocket_server().name(name).bind(host, ws_port).start_blocking() {
            Ok(h) => ws = Some(h),
            Err(e) => {
                set_error(format!("{host}:{ws_port}: {e}"));
                return std::ptr::null_mut();
            }
        }
    }
    Box::into_raw(Box::new(HfSink {
        cloth,
        fingertips,
        events,
        pins,
        json: vec![None; JSON_TOPICS.len()],
        frame: frame.to_string(),
        mcap,
        ws,
        ctx,
    }))
}

/// Declares JSON channel `which` (0 /haptics, 1 /loop, 2 /tactile) with its JSON schema. 0, or -1.
#[no_mangle]
pub extern "C" fn hf_declare_json(
    s: *mut HfSink,
    which: i32,
    schema_name: *const c_char,
    schema: *const c_char,
) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    let Some(topic) = JSON_TOPICS.get(which as usize) else {
        set_error(format!("json channel {which}: unknown"));
        return -1;
    };
    let (Some(name), Some(schema)) = (str_arg(schema_name, "schema name"), str_arg(schema, "schema")) else {
        return -1;
    };
    let built = s
        .ctx
        .channel_builder(*topic)
        .message_encoding("json")
        .schema(Schema::new(name, "jsonschema", schema.as_bytes().to_vec()))
        .build_raw();
    match built {
        Ok(c) => {
            s.json[which as usize] = Some(c);
            0
        }
        Err(e) => {
            set_error(format!("{topic}: {e}"));
            -1
        }
    }
}

/// The port the WebSocket server listens on (0: none).
#[no_mangle]
pub extern "C" fn hf_port(s: *const HfSink) -> u16 {
    // SAFETY: a handle from hf_open.
    unsafe { s.as_ref() }.and_then(|s| s.ws.as_ref()).map_or(0, |w| w.port())
}

/// 1 if channel `which` (0 /cloth, 1 /fingertips, 2 /haptics, 3 /loop, 4 /events, 5 /tactile,
/// 6 /tactile/pins) has a sink that takes it now (the MCAP file, or a live client subscribed to
/// it), else 0.
#[no_mangle]
pub extern "C" fn hf_wants(s: *const HfSink, which: i32) -> i32 {
    // SAFETY: a handle from hf_open.
    let Some(s) = (unsafe { s.as_ref() }) else { return 0 };
    let wanted = match which {
        0 => s.cloth.has_sinks(),
        1 => s.fingertips.has_sinks(),
        2 | 3 => s.json[(which - 2) as usize].as_ref().is_some_and(|c| c.has_sinks()),
        4 => s.events.has_sinks(),
        5 => s.json[2].as_ref().is_some_and(|c| c.has_sinks()),
        6 => s.pins.has_sinks(),
        _ => false,
    };
    wanted as i32
}

fn rgba(c: &[f32]) -> Color {
    Color { r: c[0] as f64, g: c[1] as f64, b: c[2] as f64, a: c[3] as f64 }
}

fn identity_pose(at: Vector3) -> Option<Pose> {
    Some(Pose { position: Some(at), orientation: Some(Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 }) })
}

/// /cloth: one entity "cloth", an indexed triangle list of `nv` vertices (xyz) with per-vertex
/// colours (rgba in 0..1) and `nt` triangles (3 indices each).
#[no_mangle]
pub extern "C" fn hf_cloth(
    s: *mut HfSink,
    log_time_ns: u64,
    xyz: *const f32,
    rgba_in: *const f32,
    nv: u32,
    tris: *const u32,
    nt: u32,
) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    let (xyz, col, tri) = (slice(xyz, 3 * nv as usize), slice(rgba_in, 4 * nv as usize), slice(tris, 3 * nt as usize));
    let mesh = TriangleListPrimitive {
        pose: identity_pose(Vector3 { x: 0.0, y: 0.0, z: 0.0 }),
        points: xyz.chunks_exact(3).map(|p| Point3 { x: p[0] as f64, y: p[1] as f64, z: p[2] as f64 }).collect(),
        color: None,
        colors: col.chunks_exact(4).map(rgba).collect(),
        indices: tri.to_vec(),
    };
    let entity = SceneEntity {
        timestamp: stamp(log_time_ns),
        frame_id: s.frame.clone(),
        id: "cloth".into(),
        triangles: vec![mesh],
        ..Default::default()
    };
    s.cloth.log_with_meta(&SceneUpdate { deletions: vec![], entities: vec![entity] }, meta(log_time_ns));
    0
}

/// /fingertips: per finger an entity "finger<i>" with a sphere of `radius` at the proxy centre
/// and, when the force is not zero, an arrow along it from the centre (`metres_per_newton` long
/// per N). `contact[i]` != 0 colours the sphere as touching.
#[no_mangle]
pub extern "C" fn hf_fingertips(
    s: *mut HfSink,
    log_time_ns: u64,
    n: u32,
    centres: *const f32,
    forces: *const f32,
    contact: *const u8,
    radius: f64,
    metres_per_newton: f64,
) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    let n = n as usize;
    let (c, f, touch) = (slice(centres, 3 * n), slice(forces, 3 * n), slice(contact, n));
    let mut entities = Vec::with_capacity(n);
    for i in 0..n {
        let at = Vector3 { x: c[3 * i] as f64, y: c[3 * i + 1] as f64, z: c[3 * i + 2] as f64 };
        let touching = touch.get(i).is_some_and(|&t| t != 0);
        let sphere = SpherePrimitive {
            pose: identity_pose(at),
            size: Some(Vector3 { x: 2.0 * radius, y: 2.0 * radius, z: 2.0 * radius }),
            color: Some(if touching {
                Color { r: 0.95, g: 0.55, b: 0.15, a: 0.6 }
            } else {
                Color { r: 0.6, g: 0.6, b: 0.65, a: 0.4 }
            }),
        };
        let (fx, fy, fz) = (f[3 * i] as f64, f[3 * i + 1] as f64, f[3 * i + 2] as f64);
        let norm = (fx * fx + fy * fy + fz * fz).sqrt();
        let mut arrows = vec![];
        if norm > 1e-9 && norm.is_finite() {
            // The rotation taking +x (the arrow's axis) onto the force direction.
            let (dx, dy, dz) = (fx / norm, fy / norm, fz / norm);
            let q = if dx < -1.0 + 1e-9 {
                Quaternion { x: 0.0, y: 0.0, z: 1.0, w: 0.0 }
            } else {
                let (w, x, y, z) = (1.0 + dx, 0.0, -dz, dy);
                let qn = (w * w + x * x + y * y + z * z).sqrt();
                Quaternion { x: x / qn, y: y / qn, z: z / qn, w: w / qn }
            };
            let length = norm * metres_per_newton;
            arrows.push(ArrowPrimitive {
                pose: Some(Pose { position: Some(at), orientation: Some(q) }),
                shaft_length: 0.75 * length,
                shaft_diameter: 0.1 * radius,
                head_length: 0.25 * length,
                head_diameter: 0.3 * radius,
                color: Some(Color { r: 0.8, g: 0.1, b: 0.1, a: 1.0 }),
            });
        }
        entities.push(SceneEntity {
            timestamp: stamp(log_time_ns),
            frame_id: s.frame.clone(),
            id: format!("finger{i}"),
            spheres: vec![sphere],
            arrows,
            ..Default::default()
        });
    }
    s.fingertips.log_with_meta(&SceneUpdate { deletions: vec![], entities }, meta(log_time_ns));
    0
}

/// A JSON message on channel `which` (0 /haptics, 1 /loop, 2 /tactile), declared by
/// hf_declare_json.
#[no_mangle]
pub extern "C" fn hf_json(s: *mut HfSink, which: i32, log_time_ns: u64, json: *const u8, len: usize) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    match s.json.get(which as usize) {
        Some(Some(c)) => {
            c.log_with_meta(slice(json, len), meta(log_time_ns));
            0
        }
        _ => {
            set_error(format!("json channel {which}: not declared"));
            -1
        }
    }
}

/// /tactile/pins: an 8-bit grey image (`mono8`) of `width` x `height` pixels, `width` bytes a
/// row, in the scene's frame.
#[no_mangle]
pub extern "C" fn hf_pins(s: *mut HfSink, log_time_ns: u64, width: u32, height: u32, grey: *const u8) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    let image = RawImage {
        timestamp: stamp(log_time_ns),
        frame_id: s.frame.clone(),
        width,
        height,
        encoding: "mono8".to_string(),
        step: width,
        data: slice(grey, (width as usize) * (height as usize)).to_vec().into(),
    };
    s.pins.log_with_meta(&image, meta(log_time_ns));
    0
}

/// /events: a foxglove.Log with `level` (1 debug, 2 info, 3 warning, 4 error, 5 fatal), `name`
/// (the event's kind) and `message`.
#[no_mangle]
pub extern "C" fn hf_event(
    s: *mut HfSink,
    log_time_ns: u64,
    level: i32,
    name: *const c_char,
    message: *const c_char,
) -> i32 {
    let Some(s) = sink(s) else { return -1 };
    let (Some(name), Some(message)) = (str_arg(name, "event kind"), str_arg(message, "event text")) else {
        return -1;
    };
    let log = Log {
        timestamp: stamp(log_time_ns),
        level,
        message: message.to_string(),
        name: name.to_string(),
        file: String::new(),
        line: 0,
    };
    s.events.log_with_meta(&log, meta(log_time_ns));
    0
}

/// Stops the server (its clients are dropped), finishes the MCAP file (summary and footer) and
/// frees the handle. 0, or -1 if the file could not be finished.
#[no_mangle]
pub extern "C" fn hf_close(s: *mut HfSink) -> i32 {
    if s.is_null() {
        return 0;
    }
    // SAFETY: a handle from hf_open, closed once.
    let s = unsafe { Box::from_raw(s) };
    let HfSink { cloth, fingertips, events, pins, json, mcap, ws, .. } = *s;
    if let Some(w) = ws {
        w.stop().wait_blocking();
    }
    let mut rc = 0;
    if let Some(m) = mcap {
        if let Err(e) = m.close() {
            set_error(format!("mcap: {e}"));
            rc = -1;
        }
    }
    drop((cloth, fingertips, events, pins, json));
    rc
}
