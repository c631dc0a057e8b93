"""Tests of the platform-timer benchmark (devices/hal/platform_timer.cpp: `hapticloth-bench
timer`) against cyclictest of Debian's rt-tests, which measures the same thing: the wake-up
latency of a SCHED_FIFO 80 thread sleeping to absolute 1 kHz deadlines with
/dev/cpu_dma_latency held at 0. And that `hapticloth-bench udp` prints that figure beside its
own, with the excess. Both runs are short and alternate, so they see the same machine; what is
checked is that the two tools agree on the typical wake-up (a wrong clock, unit or sleep would
be off by orders of magnitude), not any timing target (those live in the benchmarks)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest

from buildpaths import program

KEYS = ("ticks", "p50_us", "p99_us", "p999_us", "max_us", "over_1ms")


def timer(ticks: int) -> dict:
    r = subprocess.run([str(program("hapticloth-bench")), "timer", "--ticks", str(ticks), "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def cyclictest_avg_us(loops: int) -> float:
    exe = shutil.which("cyclictest")
    assert exe, "cyclictest (Debian's rt-tests) is installed by tools/setup"
    r = subprocess.run([exe, "-m", "-p80", "-i1000", f"-l{loops}", "-t1", "-q"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    m = re.search(r"Avg:\s*(\d+)", r.stdout)
    assert m, r.stdout
    return float(m.group(1))


def test_timer_agrees_with_cyclictest():
    ours, theirs = [], []
    for _ in range(2):  # alternate, so that both see the machine's same moments
        t = timer(2000)
        assert all(k in t for k in KEYS), t
        assert t["ticks"] == 2000
        assert 0.0 <= t["p50_us"] <= t["p99_us"] <= t["p999_us"] <= t["max_us"]
        assert 0 <= t["over_1ms"] <= t["ticks"]
        ours.append(t["mean_us"])
        theirs.append(cyclictest_avg_us(2000))
    a, b = min(ours), min(theirs)
    print(f"mean wake-up: hapticloth-bench timer {ours} us, cyclictest {theirs} us")
    assert abs(a - b) <= max(15.0, b), (ours, theirs)


def udp_bench(clock: str) -> dict:
    r = subprocess.run([str(program("hapticloth-bench")), "udp", "--duration", "1", "--clock", clock,
                        "--json"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    j = json.loads(r.stdout)
    assert j["clock"] == clock
    # The platform timer ran in the same invocation, one wake-up per packet.
    assert j["platform_timer"]["ticks"] == j["packets"]
    assert "rtt_p99_excess_us" in j
    return j


@pytest.mark.parametrize("clock", ["device", "loop"])
def test_udp_bench_reports_the_platform_beside(clock):
    j = udp_bench(clock)
    if clock == "loop":
        # On its own clock the round trip is the rig's lead plus the turnaround: never less
        # than the lead. (Whether the device's clock answers sooner is the benchmark's figure;
        # that it ticks on the rig's samples is test_udp_device's.)
        assert j["rtt_us"]["p50"] >= j["lead_us"], j
