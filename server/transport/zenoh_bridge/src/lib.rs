//! A small C ABI over the zenoh session API, for the hapticloth server (C++).
//!
//! Every handle is an opaque pointer owned by the caller and freed by its own `*_close` /
//! `*_undeclare` function. Functions that can fail return NULL or a negative number and leave a
//! message for `hz_last_error` (per thread). Callbacks run on zenoh's own threads; they must
//! return quickly and must not unwind (C++ callers catch everything).
//!
//! Declared in server/transport/zenoh_bridge/include/zenoh_bridge.h.

use std::cell::RefCell;
use std::ffi::{c_char, c_void, CStr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, RwLock};

use zenoh::matching::MatchingListener;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::query::{Query, Queryable};
use zenoh::sample::Sample;
use zenoh::{Config, Session, Wait};

mod foxglove_sink;

thread_local! {
    static LAST_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

fn set_error(msg: impl Into<String>) {
    LAST_ERROR.with(|e| *e.borrow_mut() = msg.into());
}

/// Copies the calling thread's last error message (NUL-terminated, truncated to `cap`) and
/// returns its full length.
#[no_mangle]
pub extern "C" fn hz_last_error(buf: *mut c_char, cap: usize) -> usize {
    LAST_ERROR.with(|e| {
        let s = e.borrow();
        if !buf.is_null() && cap > 0 {
            let n = s.len().min(cap - 1);
            // SAFETY: the caller gives a buffer of `cap` bytes.
            unsafe {
                std::ptr::copy_nonoverlapping(s.as_ptr(), buf as *mut u8, n);
                *buf.add(n) = 0;
            }
        }
        s.len()
    })
}

fn str_arg<'a>(p: *const c_char, what: &str) -> Option<&'a str> {
    if p.is_null() {
        set_error(format!("{what}: null"));
        return None;
    }
    // SAFETY: the caller passes a NUL-terminated string that outlives the call.
    match unsafe { CStr::from_ptr(p) }.to_str() {
        Ok(s) => Some(s),
        Err(_) => {
            set_error(format!("{what}: not UTF-8"));
            None
        }
    }
}

/// The session of a handle; None (and the error set) for a null handle.
fn session_arg<'a>(s: *const HzSession) -> Option<&'a Session> {
    if s.is_null() {
        set_error("session: null");
        return None;
    }
    // SAFETY: a live session handle.
    Some(unsafe { &(*s).session })
}

/// A copy of the `len` bytes at `data` (not null when `len` > 0: the caller checked).
fn bytes_arg(data: *const u8, len: usize) -> Vec<u8> {
    if len == 0 {
        return Vec::new();
    }
    // SAFETY: `data` points to `len` readable bytes for the duration of the call.
    unsafe { std::slice::from_raw_parts(data, len) }.to_vec()
}

/// 0 for Ok; for an error, -1 and the message "`what`: error" for hz_last_error.
fn status(r: zenoh::Result<()>, what: &str) -> i32 {
    match r {
        Ok(()) => 0,
        Err(e) => {
            set_error(format!("{what}: {e}"));
            -1
        }
    }
}

/// The made handle boxed for C; for an error, NULL and the message "`what`: error" for
/// hz_last_error.
fn boxed<T>(r: zenoh::Result<T>, what: &str) -> *mut T {
    match r {
        Ok(x) => Box::into_raw(Box::new(x)),
        Err(e) => {
            set_error(format!("{what}: {e}"));
            std::ptr::null_mut()
        }
    }
}

// --- session ------------------------------------------------------------------------------

pub struct HzSession {
    session: Session,
}

fn open(config: zenoh::Result<Config>, what: &str) -> *mut HzSession {
    let config = match config {
        Ok(c) => c,
        Err(e) => {
            set_error(format!("{what}: {e}"));
            return std::ptr::null_mut();
        }
    };
    boxed(zenoh::open(config).wait().map(|session| HzSession { session }), "zenoh open")
}

/// Opens a session from a JSON5 configuration text. NULL on error.
#[no_mangle]
pub extern "C" fn hz_open_json5(json5: *const c_char) -> *mut HzSession {
    let Some(text) = str_arg(json5, "config") else { return std::ptr::null_mut() };
    open(Config::from_json5(text), "zenoh config")
}

/// Opens a session from a JSON5 configuration file. NULL on error.
#[no_mangle]
pub extern "C" fn hz_open_file(path: *const c_char) -> *mut HzSession {
    let Some(p) = str_arg(path, "config path") else { return std::ptr::null_mut() };
    open(Config::from_file(p), &format!("zenoh config {p}"))
}

/// Closes the session (and with it everything declared on it) and frees the handle.
#[no_mangle]
pub extern "C" fn hz_close(s: *mut HzSession) {
    if s.is_null() {
        return;
    }
    // SAFETY: `s` came from hz_open_* and is not used again.
    let s = unsafe { Box::from_raw(s) };
    let _ = s.session.close().wait();
}

// --- publisher ----------------------------------------------------------------------------

pub struct HzPublisher {
    publisher: Publisher<'static>,
    matching: Arc<AtomicBool>,
    _listener: Option<MatchingListener<()>>,
}

/// Declares a publisher on `key` that tracks whether any subscriber matches it (see
/// hz_publisher_matching). Puts are dropped, never blocked, under congestion. NULL on error.
#[no_mangle]
pub extern "C" fn hz_declare_publisher(s: *const HzSession, key: *const c_char) -> *mut HzPublisher {
    let Some(session) = session_arg(s) else { return std::ptr::null_mut() };
    let Some(key) = str_arg(key, "key expression") else { return std::ptr::null_mut() };
    let publisher = match session.declare_publisher(key.to_owned()).wait() {
        Ok(p) => p,
        Err(e) => {
            set_error(format!("declare publisher {key}: {e}"));
            return std::ptr::null_mut();
        }
    };
    let matching = Arc::new(AtomicBool::new(false));
    let flag = matching.clone();
    let listener = match publisher
        .matching_listener()
        .callback(move |st| flag.store(st.matching(), Ordering::Release))
        .wait()
    {
        Ok(l) => Some(l),
        Err(e) => {
            set_error(format!("matching listener {key}: {e}"));
            return std::ptr::null_mut();
        }
    };
    if let Ok(st) = publisher.matching_status().wait() {
        if st.matching() {
            matching.store(true, Ordering::Release);
        }
    }
    Box::into_raw(Box::new(HzPublisher { publisher, matching, _listener: listener }))
}

/// 1 if at least one subscriber matches the publisher's key expression, else 0.
#[no_mangle]
pub extern "C" fn hz_publisher_matching(p: *const HzPublisher) -> i32 {
    if p.is_null() {
        return 0;
    }
    // SAFETY: a live publisher handle.
    unsafe { (*p).matching.load(Ordering::Acquire) as i32 }
}

/// Publishes a copy of `len` bytes. 0 on success, -1 on error.
#[no_mangle]
pub extern "C" fn hz_put(p: *const HzPublisher, data: *const u8, len: usize) -> i32 {
    if p.is_null() || (data.is_null() && len > 0) {
        set_error("put: null");
        return -1;
    }
    // SAFETY: a live publisher handle.
    status(unsafe { &(*p).publisher }.put(bytes_arg(data, len)).wait(), "put")
}

#[no_mangle]
pub extern "C" fn hz_undeclare_publisher(p: *mut HzPublisher) {
    if !p.is_null() {
        // SAFETY: from hz_declare_publisher, not used again.
        let p = unsafe { Box::from_raw(p) };
        let _ = p.publisher.undeclare().wait();
    }
}

// --- subscriber ---------------------------------------------------------------------------

/// Called for every sample: payload bytes, the sample's key expression (not NUL-terminated)
/// and the caller's context pointer. The pointers are valid only during the call.
pub type HzSampleCallback =
    extern "C" fn(data: *const u8, len: usize, key: *const c_char, key_len: usize, ctx: *mut c_void);

struct Ctx(*mut c_void);
// SAFETY: the C caller promises the context may be used from zenoh's threads.
unsafe impl Send for Ctx {}
unsafe impl Sync for Ctx {}

/// Keeps C callbacks and undeclaring apart: a callback runs under the read lock and only while
/// the gate is open; closing it takes the write lock, so it waits for callbacks in flight on
/// zenoh's threads (zenoh's undeclare alone does not), and none runs after it. The C context
/// may then be freed.
#[derive(Clone)]
struct Gate(Arc<RwLock<bool>>);

impl Gate {
    fn new() -> Self {
        Gate(Arc::new(RwLock::new(true)))
    }
    fn run(&self, f: impl FnOnce()) {
        let open = self.0.read().unwrap_or_else(|e| e.into_inner());
        if *open {
            f();
        }
    }
    fn close(&self) {
        *self.0.write().unwrap_or_else(|e| e.into_inner()) = false;
    }
}

/// The C callback `f` (called with the caller's context) as zenoh's callback, behind a new gate:
/// returns the gate, to close before undeclaring, and the callback.
fn behind_gate<A>(
    ctx: *mut c_void,
    f: impl Fn(*mut c_void, A) + Send + Sync + 'static,
) -> (Gate, impl Fn(A) + Send + Sync + 'static) {
    let ctx = Ctx(ctx);
    let gate = Gate::new();
    let g = gate.clone();
    (gate, move |a| {
        let c = &ctx; // the whole Ctx (Send), not its raw pointer field
        g.run(|| f(c.0, a))
    })
}

/// The session and key expression of a declaration, or None with the error set.
fn declare_args<'a>(s: *const HzSession, key: *const c_char) -> Option<(&'a Session, &'a str)> {
    Some((session_arg(s)?, str_arg(key, "key expression")?))
}

/// Closes the handle's gate (no C callback runs after it), then undeclares with `undeclare`.
fn undeclare_gated<T>(handle: *mut T, gate: impl Fn(&T) -> &Gate, undeclare: impl FnOnce(T)) {
    if !handle.is_null() {
        // SAFETY: from one of the hz_declare_* functions, not used again.
        let h = unsafe { Box::from_raw(handle) };
        gate(&h).close();
        undeclare(*h);
    }
}

pub struct HzSubscriber {
    _subscriber: Subscriber<()>,
    gate: Gate,
}

/// Declares a subscriber on `key` that calls `cb(…, ctx)` for every sample. NULL on error.
#[no_mangle]
pub extern "C" fn hz_declare_subscriber(
    s: *const HzSession,
    key: *const c_char,
    cb: HzSampleCallback,
    ctx: *mut c_void,
) -> *mut HzSubscriber {
    let Some((session, key)) = declare_args(s, key) else { return std::ptr::null_mut() };
    let (gate, callback) = behind_gate(ctx, move |c, sample: Sample| {
        let payload = sample.payload().to_bytes();
        let k = sample.key_expr().as_str();
        cb(payload.as_ptr(), payload.len(), k.as_ptr() as *const c_char, k.len(), c);
    });
    let r = session.declare_subscriber(key.to_owned()).callback(callback).wait();
    boxed(r.map(|sub| HzSubscriber { _subscriber: sub, gate }), &format!("declare subscriber {key}"))
}

/// Undeclares the subscriber; when it returns, no callback is running or will run.
#[no_mangle]
pub extern "C" fn hz_undeclare_subscriber(sub: *mut HzSubscriber) {
    undeclare_gated(sub, |h| &h.gate, |h| {
        let _ = h._subscriber.undeclare().wait();
    });
}

// --- queryable ----------------------------------------------------------------------------

/// A query being answered; valid only during the query callback.
pub struct HzQuery<'a> {
    query: &'a Query,
    reply_key: &'a str,
}

/// Called for every query, with the queried key expression (not NUL-terminated). Reply with
/// hz_query_reply during the call.
pub type HzQueryCallback =
    extern "C" fn(query: *const HzQuery, key: *const c_char, key_len: usize, ctx: *mut c_void);

pub struct HzQueryable {
    _queryable: Queryable<()>,
    gate: Gate,
}

/// Declares a queryable on `key`. NULL on error. Declared as hz_declare_subscriber declares its
/// subscriber: the C callback runs behind a gate, boxed with the handle (see Gate).
#[no_mangle]
pub extern "C" fn hz_declare_queryable(
    s: *const HzSession,
    key: *const c_char,
    cb: HzQueryCallback,
    ctx: *mut c_void,
) -> *mut HzQueryable {
    let Some((session, key)) = declare_args(s, key) else { return std::ptr::null_mut() };
    let reply_key = key.to_owned();
    let (gate, callback) = behind_gate(ctx, move |c, query: Query| {
        let q = HzQuery { query: &query, reply_key: &reply_key };
        let k = query.key_expr().as_str();
        cb(&q, k.as_ptr() as *const c_char, k.len(), c);
    });
    let r = session.declare_queryable(key.to_owned()).callback(callback).wait();
    boxed(r.map(|q| HzQueryable { _queryable: q, gate }), &format!("declare queryable {key}"))
}

/// Replies to `query` with `len` bytes on the queryable's own key expression (which must be
/// concrete: a client may query with wildcards, a reply may not carry them). 0 or -1.
#[no_mangle]
pub extern "C" fn hz_query_reply(query: *const HzQuery, data: *const u8, len: usize) -> i32 {
    if query.is_null() || (data.is_null() && len > 0) {
        set_error("reply: null");
        return -1;
    }
    // SAFETY: a live query (inside its callback).
    let q = unsafe { &*query };
    status(q.query.reply(q.reply_key.to_owned(), bytes_arg(data, len)).wait(), "reply")
}

#[no_mangle]
pub extern "C" fn hz_undeclare_queryable(q: *mut HzQueryable) {
    undeclare_gated(q, |h| &h.gate, |h| {
        let _ = h._queryable.undeclare().wait();
    });
}

// --- get ----------------------------------------------------------------------------------

/// Queries `selector` and calls `cb` for every successful reply (on the calling thread); waits
/// for all replies or `timeout_ms`. Returns the number of replies, or -1 on error.
#[no_mangle]
pub extern "C" fn hz_get(
    s: *const HzSession,
    selector: *const c_char,
    timeout_ms: u64,
    cb: HzSampleCallback,
    ctx: *mut c_void,
) -> i32 {
    let Some(session) = session_arg(s) else { return -1 };
    let Some(sel) = str_arg(selector, "selector") else { return -1 };
    let replies = match session
        .get(sel.to_owned())
        .timeout(std::time::Duration::from_millis(timeout_ms))
        .wait()
    {
        Ok(r) => r,
        Err(e) => {
            set_error(format!("get {sel}: {e}"));
            return -1;
        }
    };
    let mut n = 0;
    while let Ok(reply) = replies.recv() {
        if let Ok(sample) = reply.result() {
            let payload = sample.payload().to_bytes();
            let k = sample.key_expr().as_str();
            cb(payload.as_ptr(), payload.len(), k.as_ptr() as *const c_char, k.len(), ctx);
            n += 1;
        }
    }
    n
}
