"""hapticloth-bench haptic --subscribers N: the haptic loop's period error while N subscribers
(half over zenoh, half over LCM) take every topic the server publishes at a 120 Hz cloth rate,
against the same server publishing to nobody, beside the platform's own timer.
With --foxglove-clients N instead: the server serves the Foxglove live view (--foxglove) in
every run, and N of Foxglove's own WebSocket clients (tests/node) take every channel in the
"on" runs.

The figures are the median of 3 alternating off/on pairs in this one invocation (off-on,
on-off, off-on: a machine that drifts over the minute shifts both sides alike), each pair with
the platform timer (`hapticloth-bench timer`, same ticks) measured right after it. The whole
measurement runs inside a network namespace this program makes (`unshare --net`): zenoh on its
loopback over tcp, LCM udpm with ttl 0, so no multicast leaves it.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from .bench_transport import find_binary
from .client import Client
from .errors import UserError, check_number, run_cli

LCM_URL = "udpm://239.255.76.67:7667?ttl=0"
TOPICS = ("cloth", "haptics", "stats", "events")

# One subscriber process: every topic, counting what arrives for argv[3] seconds from the first
# haptic sample (the server answers from before its preroll; its session starts after it), the
# wait for that bounded by a minute.
SUBSCRIBER = r"""
import sys, time
from hapticloth.client import Client
transport, where, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
c = (Client("zenoh", server="bench", endpoint=where) if transport == "zenoh"
     else Client("lcm", server="bench", lcm_url=where))
n = {"count": 0, "haptics": 0}
def got(m):
    n["count"] += 1
def got_haptics(m):
    n["haptics"] += 1
    got(m)
for t in ("cloth", "stats", "events"):
    c.subscribe(t, got, raw=True)
c.subscribe("haptics", got_haptics, raw=True)
print("ready", flush=True)
first = time.monotonic() + 60
while n["haptics"] == 0 and time.monotonic() < first:
    time.sleep(0.01)
end = time.monotonic() + seconds
while time.monotonic() < end:
    time.sleep(0.05)
print(n["count"], flush=True)
c.close()
"""


def wait_for_server(srv, endpoint, deadline_s=30.0):
    """Until the server answers a scene request over zenoh (bounded)."""
    deadline = time.monotonic() + deadline_s
    while True:
        try:
            with Client("zenoh", server="bench", endpoint=endpoint) as c:
                c.get_scene(timeout=1.0)
            return
        except Exception:
            if time.monotonic() > deadline or srv.poll() is not None:
                raise UserError(f"the server did not answer on {endpoint} within {deadline_s:g} s")
            time.sleep(0.2)


REPO = Path(__file__).resolve().parents[3]
#: Foxglove's own WebSocket client (installed by tools/setup)
NODE_CLIENT = REPO / "tests" / "node" / "foxglove_client.mjs"


def start_subscriber(i, endpoint, seconds, foxglove_port):
    """Subscriber i: Foxglove's client when the live view is on, else zenoh (even i) or LCM."""
    if foxglove_port:
        node = shutil.which("node")
        if not node or not (NODE_CLIENT.parent / "node_modules").is_dir():
            raise UserError("--foxglove-clients needs node and tests/node/node_modules (tools/setup)")
        cmd, transport = [node, str(NODE_CLIENT), f"ws://127.0.0.1:{foxglove_port}", "subscribe", str(seconds)], "foxglove"
    else:
        transport, where = ("zenoh", endpoint) if i % 2 == 0 else ("lcm", LCM_URL)
        cmd = [sys.executable, "-c", SUBSCRIBER, transport, where, str(seconds)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    p.stdout.readline()  # "ready"
    return transport, p


def received_count(transport, out):
    lines = out.strip().splitlines()
    if not lines:
        return 0
    if transport == "foxglove":
        return sum(json.loads(lines[-1]).get("messages", {}).values())
    return int(lines[-1])


def one_run(subscribers, seconds, cloth_rate, port, foxglove_port=0):
    """One server run publishing on zenoh and LCM (and the Foxglove live view on
    `foxglove_port`, if not 0) with `subscribers` subscribers; returns the server's haptic
    statistics and what each subscriber received."""
    server = find_binary("hapticloth-server")
    scene = REPO / "tools" / "scenes" / "hanging_square.toml"
    endpoint = f"tcp/127.0.0.1:{port}"
    cmd = [server, "--scene", str(scene), "--json", "--name", "bench", "--duration", str(seconds),
           "--zenoh-listen", endpoint, "--lcm-url", LCM_URL, "--no-lcm-log",
           "--cloth-rate", str(cloth_rate)]
    if foxglove_port:
        cmd += ["--foxglove", f"127.0.0.1:{foxglove_port}"]
    srv = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    subs = []
    try:
        wait_for_server(srv, endpoint)
        for i in range(subscribers):
            subs.append(start_subscriber(i, endpoint, seconds, foxglove_port))
        out, err = srv.communicate(timeout=seconds + 60)
        received = []
        for transport, p in subs:
            o, _ = p.communicate(timeout=seconds + 30)
            received.append({"transport": transport, "messages": received_count(transport, o)})
    finally:
        for _, p in subs:
            if p.poll() is None:
                p.kill()
                p.wait()
        if srv.poll() is None:
            srv.kill()
            srv.wait()
    if srv.returncode != 0:
        raise UserError(f"the server exited {srv.returncode}: {err.strip()[-300:]}")
    j = json.loads(out.strip().splitlines()[-1])
    return {"subscribers": subscribers, "period_error_p99_us": j["period_error_us"]["p99"],
            "period_error_max_us": j["period_error_us"]["max"],
            "missed_deadlines": j["missed_deadlines"], "ticks": j["haptic_ticks"],
            "realtime_scheduling": j.get("realtime_scheduling"), "received": received}


def platform_timer(seconds):
    bench = find_binary("hapticloth-bench")
    p = subprocess.run([bench, "timer", "--ticks", str(int(seconds * 1000)), "--json"],
                       capture_output=True, text=True, timeout=seconds + 60)
    if p.returncode != 0:
        raise UserError(f"hapticloth-bench timer failed: {p.stderr.strip()[-300:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def measure(subscribers, seconds, cloth_rate, port, pairs=3, foxglove_port=0):
    runs = []
    for k in range(pairs):
        order = (0, subscribers) if k % 2 == 0 else (subscribers, 0)
        pair = {}
        for n in order:
            pair["on" if n else "off"] = one_run(n, seconds, cloth_rate, port, foxglove_port)
        pair["platform_timer"] = platform_timer(seconds)
        runs.append(pair)
    med = lambda xs: statistics.median(xs)
    off = med([r["off"]["period_error_p99_us"] for r in runs])
    on = med([r["on"]["period_error_p99_us"] for r in runs])
    plat = med([r["platform_timer"]["p99_us"] for r in runs])
    fox = bool(foxglove_port)
    return {"benchmark": "haptic-foxglove-clients" if fox else "haptic-subscribers", "subscribers": subscribers,
            "zenoh_subscribers": 0 if fox else (subscribers + 1) // 2,
            "lcm_subscribers": 0 if fox else subscribers // 2,
            "foxglove_clients": subscribers if fox else 0,
            "cloth_rate_hz": cloth_rate, "seconds_per_run": seconds, "pairs": runs,
            "off_period_error_p99_us": off, "on_period_error_p99_us": on,
            "difference_p99_us": on - off, "platform_timer_p99_us": plat,
            "on_excess_over_platform_p99_us": on - plat}


def in_namespace(argv):
    """Re-runs this program inside a new network namespace with loopback multicast for udpm."""
    if os.geteuid() != 0 or not shutil.which("unshare") or not shutil.which("ip"):
        raise UserError("--subscribers needs root, unshare and ip: LCM's udpm runs only inside a "
                        "network namespace this program makes")
    inner = ("ip link set lo up && ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo && "
             f"exec {sys.executable} -m hapticloth.bench_subscribers --inside " +
             " ".join(f"'{a}'" for a in argv))
    p = subprocess.run(["unshare", "--net", "sh", "-c", inner], capture_output=True, text=True)
    sys.stderr.write(p.stderr)
    if p.returncode != 0:
        return p.returncode
    sys.stdout.write(p.stdout)
    return 0


def main(argv=None):
    return run_cli("hapticloth-bench haptic --subscribers", _main, argv)


def _main(argv):
    ap = argparse.ArgumentParser(prog="hapticloth-bench haptic --subscribers",
                                 description=__doc__.split("\n\n")[0])
    who = ap.add_mutually_exclusive_group(required=True)
    who.add_argument("--subscribers", type=int, help="subscribers (half zenoh, half LCM)")
    who.add_argument("--foxglove-clients", type=int,
                     help="Foxglove WebSocket clients (the live view on in every run)")
    ap.add_argument("--duration", type=float, default=10.0, help="seconds per server run (6 runs)")
    ap.add_argument("--cloth-rate", type=float, default=120.0, help="Hz of the cloth state")
    ap.add_argument("--port", type=int, default=17700, help="zenoh tcp port inside the namespace")
    ap.add_argument("--json", action="store_true", help="one JSON object on one line")
    ap.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.subscribers is not None:
        check_number("--subscribers", a.subscribers, "a number of subscribers from 1 to 16", 1, 16)
    else:
        check_number("--foxglove-clients", a.foxglove_clients, "a number of clients from 1 to 16", 1, 16)
    check_number("--duration", a.duration, "a positive number of seconds", 0.0, 600.0,
                 low_open=True, unit=" s")
    check_number("--cloth-rate", a.cloth_rate, "a rate in Hz", 0.0, 1000.0, low_open=True, unit=" Hz")
    check_number("--port", a.port, "a tcp port from 1 to 65535", 1, 65535)
    if not a.inside:
        return in_namespace([x for x in (argv if argv is not None else sys.argv[1:])])
    if a.subscribers is not None:
        res = measure(a.subscribers, a.duration, a.cloth_rate, a.port)
    else:  # the live view's port beside zenoh's
        res = measure(a.foxglove_clients, a.duration, a.cloth_rate, a.port, foxglove_port=a.port + 1)
    print(json.dumps(res) if a.json else json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
