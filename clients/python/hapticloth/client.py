"""Client of a hapticloth server: subscribe to its state, ask for the scene, inject fingertip
trajectories, record and replay.

The server publishes LCM-encoded messages (proto/*.lcm) on zenoh key expressions
``hapticloth/<server>/<topic>`` and on LCM channels ``HAPTICLOTH_<TOPIC>``; see
server/transport/hub.hpp for the table. Callbacks run on the transport's receive thread: keep
them short (a slow callback delays this client's later messages, never the server).

    from hapticloth.client import Client
    with Client("zenoh", server="default", endpoint="tcp/127.0.0.1:7447") as c:
        scene = c.get_scene()
        c.subscribe_haptics(lambda m: print(m.force[0]))
        c.inject_trajectory(0, [0.5, 1.0], [[0, 0, 0.0], [0.02, 0, 0.0]])
"""

import math
import os
import struct
import threading
import time

from . import lcmtypes
from .errors import UserError
from .lcmtypes import channel, decoder, event_t, scene_info_t, scene_request_t, trajectory_cmd_t

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
#: LCM's default multicast group with ttl=0: never leaves the host (tests: only inside a
#: network namespace they made).
DEFAULT_LCM_URL = "udpm://239.255.76.67:7667?ttl=0"
FRAMES = {"device": trajectory_cmd_t.FRAME_DEVICE, "scene": trajectory_cmd_t.FRAME_SCENE}


def zenoh_client_config(endpoint):
    """JSON5 for a zenoh client that connects to `endpoint` only (no scouting)."""
    return ('{ mode: "client", connect: { endpoints: ["%s"] }, '
            'scouting: { multicast: { enabled: false }, gossip: { enabled: false } } }' % endpoint)


def now_utime():
    return int(time.time() * 1e6)


class Client:
    """One connection to a server, over zenoh or LCM.

    transport: "zenoh" (tcp to `endpoint`, or the JSON5 file `zenoh_config`) or "lcm"
    (the provider `lcm_url`). server: the server's name (its --name).
    """

    def __init__(self, transport="zenoh", server="default", endpoint=DEFAULT_ENDPOINT,
                 lcm_url=DEFAULT_LCM_URL, zenoh_config=None, source=None):
        if transport not in ("zenoh", "lcm"):
            raise ValueError(f"transport must be 'zenoh' or 'lcm', not {transport!r}")
        self.transport = transport
        self.server = server
        self.source = source or f"python-{os.getpid()}"
        self._seq = 0
        self._lock = threading.Lock()
        self._subs = []
        self._acks = {}
        self._ack_cv = threading.Condition()
        self._ack_sub = None
        self._closed = False
        if transport == "zenoh":
            import zenoh
            conf = (zenoh.Config.from_file(zenoh_config) if zenoh_config
                    else zenoh.Config.from_json5(zenoh_client_config(endpoint)))
            self._z = zenoh.open(conf)
        else:
            import lcm
            self._lc = lcm.LCM(lcm_url)
            self._rx = threading.Thread(target=self._lcm_loop, name="hapticloth-lcm", daemon=True)
            self._rx.start()

    # --- plumbing ----------------------------------------------------------------------------
    def key(self, topic):
        return f"hapticloth/{self.server}/{topic}"

    def _lcm_loop(self):
        while not self._closed:
            self._lc.handle_timeout(100)

    def publish(self, topic, data):
        """Sends encoded bytes on a topic (an input of the server, or anything in tests).
        Over zenoh the put waits for room in the session's send queue: zenoh's default for a put
        is to drop the message when the queue is full, and two 100 KB trajectories sent back to
        back (a replay of both fingers) could lose the second one without a trace. A client's
        inputs are few and must arrive; the server's real-time outputs are the ones dropped."""
        if self.transport == "zenoh":
            import zenoh
            self._z.put(self.key(topic), data, congestion_control=zenoh.CongestionControl.BLOCK)
        else:
            self._lc.publish(channel(topic), data)

    def subscribe(self, topic, cb, raw=False):
        """Calls cb(message) for every message on `topic` (decoded, or bytes if raw)."""
        cls = decoder(topic)

        def deliver(data):
            cb(data if raw else cls.decode(data))

        if self.transport == "zenoh":
            sub = self._z.declare_subscriber(self.key(topic), lambda s: deliver(s.payload.to_bytes()))
        else:
            sub = self._lc.subscribe(channel(topic), lambda ch, data: deliver(data))
        self._subs.append(sub)
        return sub

    def subscribe_state(self, cb):
        """cb(cloth_state_t): vertex positions at the cloth rate."""
        return self.subscribe("cloth", cb)

    def subscribe_haptics(self, cb):
        """cb(haptic_state_t): 1 kHz samples, batched."""
        return self.subscribe("haptics", cb)

    def subscribe_tactile(self, cb):
        """cb(tactile_state_t): each tick's vibration block and pin frame per finger, batched (a
        device with a tactile display only)."""
        return self.subscribe("tactile", cb)

    def subscribe_events(self, cb):
        return self.subscribe("events", cb)

    def subscribe_stats(self, cb):
        return self.subscribe("stats", cb)

    # --- scene ---------------------------------------------------------------------------------
    def get_scene(self, timeout=5.0):
        """The scene_info_t (with the topology). zenoh: the server's queryable; LCM: a
        scene_request_t, repeated every 0.5 s until the answer or `timeout`."""
        deadline = time.monotonic() + timeout
        if self.transport == "zenoh":
            while time.monotonic() < deadline:
                left = max(0.1, min(2.0, deadline - time.monotonic()))
                for reply in self._z.get(self.key("scene"), timeout=left):
                    if reply.ok is not None:
                        return scene_info_t.decode(reply.ok.payload.to_bytes())
                time.sleep(0.05)
            raise TimeoutError(f"no scene from {self.key('scene')} within {timeout} s")
        got = []
        ev = threading.Event()

        def on_scene(m):
            if m.server_name == self.server and not got:
                got.append(m)
                ev.set()

        sub = self.subscribe("scene", on_scene)
        try:
            while time.monotonic() < deadline and not ev.is_set():
                req = scene_request_t()
                req.utime = now_utime()
                req.source = self.source
                self.publish("scene_request", req.encode())
                ev.wait(min(0.5, max(0.0, deadline - time.monotonic())))
        finally:
            self._lc.unsubscribe(sub)
            self._subs.remove(sub)
        if not got:
            raise TimeoutError(f"no scene on {channel('scene')} within {timeout} s")
        return got[0]

    # --- trajectories ------------------------------------------------------------------------
    def _on_event(self, e):
        tag = f"from '{self.source}' seq "
        i = e.text.find(tag)
        if i < 0 or e.kind not in ("command_accepted", "command_rejected"):
            return
        seq = int(e.text[i + len(tag):].split(":")[0].split()[0])
        with self._ack_cv:
            self._acks[seq] = (e.kind == "command_accepted", e.text)
            self._ack_cv.notify_all()

    def listen_for_answers(self):
        """Starts collecting the server's accept/reject events for this client's commands
        (wait_ack reads them). Call it before sending: an answer that comes before the
        subscription is lost."""
        with self._lock:
            if self._ack_sub is None:
                self._ack_sub = self.subscribe_events(self._on_event)

    def inject_trajectory(self, finger, times, positions, frame="device", wait=None, utime=None):
        """Sends a trajectory_cmd_t: the finger moves in a straight line to positions[0]
        (reached times[0] s after the server takes it), then through the points (m, `frame`
        "device" or "scene"). Returns the command's sequence number; with wait=seconds, returns
        (seq, accepted, text) from the server's event, or raises TimeoutError. Commands given
        the same `utime` are one batch: they start together (see `send`)."""
        if wait:
            self.listen_for_answers()
        seq = self.send(trajectory_message(finger, times, positions, frame), utime)
        if not wait:
            return seq
        return (seq,) + self.wait_ack(seq, wait)

    def send(self, m, utime=None):
        """Sends the trajectory_cmd_t `m` as this client's next command (its source, seq and
        utime are set here; `utime` gives the send time of a batch: the server starts the
        commands of one source and utime together, at the tick it took the first of them, so
        two fingers sent back to back move in step however far apart they arrive); returns its
        sequence number."""
        with self._lock:
            self._seq += 1
            m.seq = self._seq
        m.source = self.source
        m.utime = now_utime() if utime is None else utime
        self.publish("trajectory", m.encode())
        return m.seq

    def inject_trajectories(self, trajectories, frame="device", wait=None):
        """Several fingers at once: `trajectories` maps finger -> (times, positions). All are
        sent back to back (so the server takes them within a tick or two of each other), then,
        with wait=seconds, the answers are awaited: returns {finger: (seq, accepted, text)}."""
        if wait:
            self.listen_for_answers()
        batch = now_utime()
        seqs = {f: self.inject_trajectory(f, t, p, frame=frame, utime=batch)
                for f, (t, p) in trajectories.items()}
        if not wait:
            return seqs
        return {f: (seq,) + self.wait_ack(seq, wait) for f, seq in seqs.items()}

    def wait_ack(self, seq, timeout):
        """(accepted, text) of the server's event for command `seq`."""
        deadline = time.monotonic() + timeout
        with self._ack_cv:
            while seq not in self._acks:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"no answer to command {seq} within {timeout} s")
                self._ack_cv.wait(left)
            return self._acks[seq]

    # --- record and replay -------------------------------------------------------------------
    def record(self, path, topics=None):
        """Starts writing every message of `topics` (default: all outputs) into an LCM log at
        `path` (channels HAPTICLOTH_<TOPIC>). Returns a Recorder; stop() or use it in `with`."""
        return Recorder(self, path, topics or list(lcmtypes.TOPICS))

    def replay(self, path, mode="auto", speed=1.0, lead=0.1, max_seconds=600.0):
        """Plays a recorded LCM log back into the server (see read_replay for the modes).
        Returns the sequence numbers sent."""
        return [m.seq for m in self.play(read_replay(path, mode, speed, lead, max_seconds))]

    def play(self, commands):
        """Sends [(due, trajectory_cmd_t)] (read_replay), each `due` s after the call;
        returns the messages sent, with their sequence numbers."""
        start = time.monotonic()
        sent = []
        batch, batch_due = None, None
        for due, m in commands:
            delay = start + due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if due != batch_due:  # the commands due together are one batch: they start together
                batch, batch_due = now_utime(), due
            self.send(m, batch)
            sent.append(m)
        return sent

    # --- lifetime ------------------------------------------------------------------------------
    def close(self):
        if self._closed:
            return
        self._closed = True
        if self.transport == "zenoh":
            for s in self._subs:
                try:
                    s.undeclare()
                except Exception:
                    pass
            self._z.close()
        else:
            self._rx.join(timeout=1.0)
        self._subs.clear()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


MAX_POINTS = 4096  # the remote device's limit per command


def trajectory_message(finger, times, positions, frame="device"):
    """A trajectory_cmd_t (without source and seq: Client.send sets them)."""
    if len(times) != len(positions):
        raise ValueError("times and positions differ in length")
    m = trajectory_cmd_t()
    m.finger = int(finger)
    m.frame = FRAMES[frame]
    m.num_points = len(times)
    m.times = [float(t) for t in times]
    m.positions = [[float(c) for c in p] for p in positions]
    return m


def read_replay(path, mode="auto", speed=1.0, lead=0.1, max_seconds=600.0):
    """The commands to play back from a recorded LCM log: [(due, trajectory_cmd_t)], `due` in
    s from the start of the playback.

    mode "commands": the log's trajectory commands (HAPTICLOTH_TRAJECTORY) with their original
    spacing divided by `speed` (at most `max_seconds` after the first). mode "positions": the
    recorded device positions (HAPTICLOTH_HAPTICS) as one trajectory per finger, starting
    `lead` s after the server takes it, so the fingers repeat the recorded motion. "auto":
    commands if the log has any, else positions. Raises UserError (naming the file) when the
    log cannot be read or holds nothing to play."""
    if mode not in ("auto", "commands", "positions"):
        raise ValueError(f"mode must be auto, commands or positions, not {mode!r}")
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a positive number, not {speed!r}")
    log = lcmtypes.open_event_log(path)
    commands, samples = [], []
    try:
        for ev in log:
            if ev.channel == channel("trajectory"):
                commands.append((ev.timestamp, _decode(path, trajectory_cmd_t, ev)))
            elif ev.channel == channel("haptics"):
                samples.append(_decode(path, lcmtypes.haptic_state_t, ev))
    finally:
        log.close()
    if mode == "auto":
        mode = "commands" if commands else "positions"
    if mode == "commands":
        if not commands:
            raise UserError(f"{path}: no trajectory commands ({channel('trajectory')}) to replay")
        return _command_plan(commands, speed, max_seconds)
    plan = [(0.0, trajectory_message(f, times, points))
            for f, (times, points) in enumerate(positions_from_haptics(samples, speed, lead)) if times]
    if not plan:
        raise UserError(f"{path}: no trajectory commands ({channel('trajectory')}) or device "
                        f"positions ({channel('haptics')}) to replay")
    return plan


def _command_plan(commands, speed, max_seconds):
    """[(due, m)] from the log's [(timestamp, m)]. The timestamp is when the recorder received a
    command, so the commands of one batch (one source and utime: sent together, started together)
    can stand apart in the log by however long the recorder's thread was held up; played at those
    spacings they became separate batches, and on the stepped clock a 0.3 s gap put the replayed
    pinch's fingers 1.2 s out of step. So every command of a batch is due when its first was."""
    t0 = commands[0][0]
    first = {}
    plan = []
    for ts, m in commands:
        ts = first.setdefault((m.source, m.utime), ts)
        plan.append((min((ts - t0) / 1e6 / speed, max_seconds), m))
    plan.sort(key=lambda dm: dm[0])  # stable: a batch's commands stay in their order, together
    return plan


def _decode(path, cls, ev):
    """cls.decode of a log event; UserError naming the file and the event's channel."""
    try:
        return cls.decode(ev.data)
    except (ValueError, struct.error):
        raise UserError(f"{path}: an event on {ev.channel} is not a {cls.__name__} "
                        "(a log of another version of hapticloth?)") from None


def positions_from_haptics(samples, speed=1.0, lead=0.1, min_step=0.005):
    """Per finger (times, points) from haptic_state_t samples: device positions every
    `min_step` s at least (more if needed to stay under MAX_POINTS), times from `lead`."""
    ts, pos = [], []
    for m in samples:
        for k in range(m.num_samples):
            ts.append(m.time[k])
            pos.append(m.device_position[k])
    if not ts:
        return []
    order = sorted(range(len(ts)), key=lambda i: ts[i])
    fingers = len(pos[0])
    t0 = ts[order[0]]
    span = ts[order[-1]] - t0
    step = max(min_step, span / (MAX_POINTS - 2)) if span > 0 else min_step
    keep, next_t = [], t0
    for i in order:
        if ts[i] >= next_t - 1e-9:
            keep.append(i)
            next_t = ts[i] + step
    if keep[-1] != order[-1]:
        keep.append(order[-1])
    out = []
    for f in range(fingers):
        times = [lead + (ts[i] - t0) / speed for i in keep]
        points = [list(pos[i][f]) for i in keep]
        out.append((times, points))
    return out


#: Topics the server publishes continuously while it runs (the others come on events).
STREAMING_TOPICS = ("cloth", "haptics", "stats")


class Recorder:
    """Writes every received message into an LCM log (what lcm-logplayer and lcm.EventLog
    read). Counts per topic in `counts`."""

    def __init__(self, client, path, topics):
        import lcm
        self._log = lcm.EventLog(path, "w", overwrite=True)
        self._lock = threading.Lock()
        self._open = True
        self.path = path
        self.counts = {t: 0 for t in topics}
        #: why messages could not be written (the first failure, and how many), or ""
        self.write_error = ""
        self._write_failures = 0
        self._client = client
        # Streaming topics are declared last: a zenoh session's declarations take effect in
        # order, so once the last one delivers, every subscription before it is in place too.
        order = sorted(topics, key=lambda t: t in STREAMING_TOPICS)
        self.started_by = order[-1] if order and order[-1] in STREAMING_TOPICS else None
        self._subs = [client.subscribe(t, self._writer(t), raw=True) for t in order]

    def _writer(self, topic):
        ch = channel(topic)

        def write(data):
            with self._lock:
                if self._open:
                    try:
                        self._log.write_event(now_utime(), ch, data)
                        self.counts[topic] += 1
                    except (OSError, IOError) as e:
                        self._note_failure(e)
        return write

    def _note_failure(self, e):
        self._write_failures += 1
        first = self.write_error.split(" (", 1)[0] if self.write_error else (e.strerror or str(e))
        self.write_error = f"{first} ({self._write_failures} messages not written)"

    def wait_started(self, timeout):
        """Waits until the subscriptions are in place: the last-declared streaming topic has
        delivered a message. True at once when only event topics are recorded (nothing
        streams to prove it); False when `timeout` s pass first."""
        if self.started_by is None:
            return True
        return bool(wait_for(lambda: self.counts[self.started_by] > 0, timeout))

    def stop(self):
        c = self._client
        for s in self._subs:
            try:
                if c.transport == "zenoh":
                    s.undeclare()
                else:
                    c._lc.unsubscribe(s)
                c._subs.remove(s)
            except (ValueError, Exception):
                pass
        with self._lock:
            if self._open:
                self._open = False
                try:
                    self._log.close()
                except (OSError, IOError) as e:
                    self._note_failure(e)
        return self.counts

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def wait_for(pred, timeout, interval=0.01):
    """Polls pred() until true or `timeout` s; returns its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = pred()
        if v:
            return v
        time.sleep(interval)
    return pred()


__all__ = ["Client", "Recorder", "DEFAULT_ENDPOINT", "DEFAULT_LCM_URL", "event_t",
           "positions_from_haptics", "read_replay", "trajectory_message", "wait_for",
           "zenoh_client_config"]
