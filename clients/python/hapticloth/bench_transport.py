"""hapticloth-bench-transport: publish-to-receive latency and throughput of the cloth state of
the ~1000-triangle square (968 triangles, 529 vertices), C++ publisher (the server's Hub) to a
Python subscriber, over zenoh (tcp on 127.0.0.1) and LCM (udpm inside a network namespace this
program makes with `unshare --net`; skipped, with the reason, where that is not permitted).

Also the haptic loop's period error (the server's own statistics) with publishing off and
with four zenoh subscribers of every topic at a 120 Hz mesh rate.

Latency: the message's utime (stamped when the Hub encodes it) to its arrival in the Python
callback, same host clock. Throughput: messages and MB per second received while the publisher
encodes and sends in a tight loop.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

from .client import Client, now_utime
from .errors import UserError, check_number, run_cli


def find_binary(name):
    build = os.environ.get("HAPTICLOTH_BUILD_DIR")
    roots = [Path(build)] if build else []
    roots.append(Path(__file__).resolve().parents[3] / "build")
    for r in roots:
        for p in (r / name, r / "tools" / "bench" / name):
            if p.is_file():
                return str(p)
    found = shutil.which(name)
    if found:
        return found
    raise FileNotFoundError(f"{name} not found (build it, or set HAPTICLOTH_BUILD_DIR)")


def quantile(xs, q):
    if not xs:
        return None
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))]


def measure(transport, seconds, rate, port, lcm_url, mode):
    """Runs the publisher and a Python subscriber; returns the figures of one run."""
    pub = find_binary("hapticloth-bench-transport-pub")
    args = [pub, "--mode", mode, "--duration", str(seconds), "--rate", str(rate), "--name", "bench"]
    if transport == "zenoh":
        endpoint = f"tcp/127.0.0.1:{port}"
        args += ["--zenoh-listen", endpoint]
    else:
        args += ["--zenoh-listen", "", "--lcm-url", lcm_url]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
    lat, sizes = [], []
    lock = threading.Lock()

    def on_raw(data):
        t = now_utime()
        # utime is the first field of cloth_state_t, after the 8-byte fingerprint.
        u = int.from_bytes(data[8:16], "big", signed=True)
        with lock:
            lat.append(t - u)
            sizes.append(len(data))

    client = None
    try:
        deadline = time.monotonic() + 5.0
        while client is None:  # the publisher needs a moment to listen
            try:
                client = (Client("zenoh", server="bench", endpoint=endpoint) if transport == "zenoh"
                          else Client("lcm", server="bench", lcm_url=lcm_url))
            except Exception:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        client.subscribe("cloth", on_raw, raw=True)
        out, _ = proc.communicate(timeout=seconds + 30)
        time.sleep(0.2)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        if client:
            client.close()
    sent = json.loads(out.strip().splitlines()[-1])["sent"] if out.strip() else None
    with lock:
        lat_ = list(lat[len(lat) // 20:])  # the first 5 %: connection warm-up
        n, nbytes = len(lat), sum(sizes)
    r = {"sent": sent, "received": n, "bytes_per_message": sizes[0] if sizes else None}
    if mode == "hub":
        r.update({"rate_hz": rate, "latency_p50_us": quantile(lat_, 0.5),
                  "latency_p99_us": quantile(lat_, 0.99), "latency_max_us": max(lat_) if lat_ else None})
    else:
        r.update({"throughput_msgs_per_s": n / seconds, "throughput_MB_per_s": nbytes / seconds / 1e6})
    return r


def run_transport(transport, seconds, rate, port, lcm_url):
    latency = measure(transport, seconds, rate, port, lcm_url, "hub")
    timer = platform_timer(seconds)
    latency["platform_timer"] = timer
    if latency.get("latency_p99_us") is not None:
        latency["latency_p99_excess_us"] = latency["latency_p99_us"] - timer["p99_us"]
    return {"latency": latency, "throughput": measure(transport, seconds, rate, port, lcm_url, "raw")}


def lcm_in_namespace(argv_rest, seconds, rate):
    """Re-runs this program for LCM inside a new network namespace (udpm stays inside)."""
    if os.geteuid() != 0 or not shutil.which("unshare") or not shutil.which("ip"):
        return {"skipped": "needs root, unshare and ip to make a network namespace for udpm"}
    inner = (f"ip link set lo up && ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo && "
             f"exec {sys.executable} -m hapticloth.bench_transport --inner-lcm "
             f"--seconds {seconds} --rate {rate}")
    p = subprocess.run(["unshare", "--net", "sh", "-c", inner], capture_output=True, text=True,
                       timeout=4 * seconds + 60)
    if p.returncode != 0:
        return {"skipped": f"namespace run failed: {p.stderr.strip()[-300:]}"}
    return json.loads(p.stdout.strip().splitlines()[-1])


def platform_timer(seconds):
    """The platform's own wake-up latency (`hapticloth-bench timer`) over as many 1 kHz ticks as
    a latency run has, measured right after it."""
    bench = find_binary("hapticloth-bench")
    p = subprocess.run([bench, "timer", "--ticks", str(max(1000, int(seconds * 1000))), "--json"],
                       capture_output=True, text=True, timeout=seconds + 60)
    if p.returncode != 0:
        raise UserError(f"hapticloth-bench timer failed: {p.stderr.strip()[-300:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


TRANSPORTS = ("zenoh", "lcm")


def check_options(a):
    """UserError naming the first option out of range (every one is bounded: a typo must not
    start an hour-long run or a sleep that overflows)."""
    check_number("--seconds", a.seconds, "a positive number of seconds", 0.0, 3600.0,
                 low_open=True, unit=" s")
    check_number("--rate", a.rate, "a positive rate in Hz", 0.0, 100000.0, low_open=True, unit=" Hz")
    check_number("--port", a.port, "a tcp port from 1 to 65535", 1, 65535)
    if a.haptic_seconds is not None:
        raise UserError("--haptic-seconds: the haptic loop with subscribers is measured by "
                        "`hapticloth-bench haptic --subscribers N` now (median of 3 off/on pairs, "
                        "half zenoh, half LCM, beside the platform timer)")
    for t in a.transports.split(","):
        if t not in TRANSPORTS:
            raise UserError(f"--transports: unknown transport {t!r} (known: {', '.join(TRANSPORTS)})")


def main(argv=None):
    return run_cli("hapticloth-bench-transport", _main, argv)


def _main(argv):
    ap = argparse.ArgumentParser(prog="hapticloth-bench-transport", description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--seconds", type=float, default=5.0, help="per measurement (at most 3600)")
    ap.add_argument("--rate", type=float, default=1000.0, help="Hz of cloth states for the latency runs")
    ap.add_argument("--port", type=int, default=17500, help="zenoh tcp port on 127.0.0.1")
    ap.add_argument("--transports", default="zenoh,lcm")
    ap.add_argument("--haptic-seconds", type=float, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--inner-lcm", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    check_options(a)
    url = "udpm://239.255.76.67:7667?ttl=0"
    if a.inner_lcm:
        print(json.dumps(run_transport("lcm", a.seconds, a.rate, a.port, url)))
        return 0
    res = {"mesh": {"triangles": 968, "vertices": 529}, "seconds": a.seconds}
    for t in a.transports.split(","):
        if t == "zenoh":
            res["zenoh"] = run_transport("zenoh", a.seconds, a.rate, a.port, url)
        elif t == "lcm":
            res["lcm"] = lcm_in_namespace(argv, a.seconds, a.rate)
    if a.json:
        print(json.dumps(res))
    else:
        print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
