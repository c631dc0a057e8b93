"""Tests of the physics the benchmarks measure (hapticloth-bench accuracy, stability, limit in
their --quick forms): errors fall with the step as the integrator's order says, the solver
tolerance of the defaults does not dominate the error, the local patch renders a press that
direct coupling at a long step gets wrong, the stress map's cells hold together, and CHOLMOD's
own factorization of our matrix is what our CHOLMOD step costs at the core. Timing figures are
printed by the benchmarks, never asserted here."""

from __future__ import annotations

import json
import os
import math
import shutil
import subprocess
from pathlib import Path

import pytest

from buildpaths import program

SCENE = Path(__file__).resolve().parents[2] / "tools" / "scenes" / "hanging_square.toml"


def bench(*args, timeout=900) -> dict:
    r = subprocess.run([str(program("hapticloth-bench")), *args, "--json"], capture_output=True,
                       text=True, timeout=timeout)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def accuracy():
    return bench("accuracy", "--quick")


def runs(j, scene, sweep):
    return [r for r in j["scenes"][scene]["runs"] if r["sweep"] == sweep]


def find(rs, **kw):
    out = [r for r in rs if all(math.isclose(r[k], v) if isinstance(v, float) else r[k] == v
                                for k, v in kw.items())]
    assert len(out) == 1, (kw, [r["label"] for r in rs])
    return out[0]


def test_release_error_falls_with_the_step(accuracy):
    rs = runs(accuracy, "release", "dt-alpha")
    for alpha in (0.5, 1.0):
        errs = [find(rs, dt_ms=dt, alpha=alpha)["pos_err_mm"] for dt in (1.0, 5.0, 20.0, 40.0)]
        assert errs == sorted(errs), (alpha, errs)
    # backward Euler is first order: 5x the step gives about 5x the error (3x-7x)
    e1 = find(rs, dt_ms=1.0, alpha=1.0)["pos_err_mm"]
    e5 = find(rs, dt_ms=5.0, alpha=1.0)["pos_err_mm"]
    assert 3.0 < e5 / e1 < 7.0, (e1, e5)
    # alpha 0.5 (second order) is more accurate at the same step
    assert find(rs, dt_ms=1.0, alpha=0.5)["pos_err_mm"] < 0.7 * e1
    for r in rs:
        if r["dt_ms"] <= 5.0 or r["alpha"] == 1.0:
            assert r["stable"], r["label"]
        else:  # alpha 0.5 at 20-40 ms rings: caught as an explosion, finished at alpha 1
            assert r["stable"] or r["events"]["alpha_fallbacks"] == 1, r


def test_solver_tolerance_does_not_dominate(accuracy):
    rs = runs(accuracy, "release", "solver")
    exact = find(rs, solver="cholmod")["pos_err_mm"]
    d = accuracy["defaults"]
    default = find(rs, solver="pcg", pcg_tolerance=d["pcg_tolerance"],
                   pcg_float_matrix=d["pcg_float_matrix"])["pos_err_mm"]
    assert abs(default - exact) < 0.01 * exact, (default, exact)
    # on every mesh, the default tolerance and one 10x tighter give the same error within 1%
    res = runs(accuracy, "release", "resolution")
    for n in {r["triangles"] for r in res}:
        a, b = sorted((r for r in res if r["triangles"] == n), key=lambda r: -r["pcg_tolerance"])
        assert abs(a["pos_err_mm"] - b["pos_err_mm"]) < 0.01 * b["pos_err_mm"], (a, b)


def test_finer_mesh_is_closer_to_the_finest(accuracy):
    rs = [r for r in runs(accuracy, "release", "resolution")
          if r["pcg_tolerance"] == accuracy["defaults"]["pcg_tolerance"]]
    coarse = find(rs, triangles=242)["pos_err_mm"]
    default = find(rs, triangles=968)["pos_err_mm"]
    assert default < coarse


def test_press_force(accuracy):
    ref_force = accuracy["scenes"]["press"]["reference_max_force_n"]
    # The finger really presses the drum: several times the 29-44 mN a fingertip detects (0.18 N
    # with the drum's 15 mm elements refined under it, 0.2-0.3 N without)
    assert ref_force > 0.1
    direct = find(runs(accuracy, "press", "dt-alpha"), dt_ms=1.0, alpha=1.0)
    assert direct["force_err_rel"] < 0.3
    patch = find(runs(accuracy, "press", "local-patch"), dt_ms=20.0)
    naive = find(runs(accuracy, "press", "direct-long-step"), dt_ms=20.0)
    # the fingertip solved with the cloth in the implicit step stays stable with a 20 ms global
    # step (the force is held between steps); the local patch too
    assert naive["force_err_rel"] < 0.3, naive
    assert patch["force_err_rel"] < 0.5


def test_pinch_force_at_the_haptic_rate(accuracy):
    # The squeeze: each fingertip's device position 2 mm inside the cloth, its proxy held at the
    # cloth, so each 800 N/m coupling asks 1.6 N, less the sandwich's shift, with the lift's
    # friction beside it. (The refined compliance of a finger's first sub-millinewton touch once
    # held the squeeze at 0.17-0.8 N for a second: the 0.25 ms reference's largest force 1.0 N,
    # the 1 ms run 71% off the 0.05 ms one.)
    ref = accuracy["scenes"]["pinch"]["reference_max_force_n"]
    assert 1.3 < ref < 1.8, ref
    direct = find(runs(accuracy, "pinch", "dt-alpha"), dt_ms=1.0, alpha=1.0)
    assert direct["force_err_rel"] < 0.05, direct
    for r in runs(accuracy, "pinch", "local-response"):
        assert r["force_err_rel"] < 0.1, r


def test_pareto_front(accuracy):
    for name, sc in accuracy["scenes"].items():
        front = [r for r in sc["runs"] if r["pareto"]]
        assert front, name
        assert all(r["stable"] for r in front)
        # no front run is beaten on both axes by another stable candidate
        key = "pos_err_mm" if name == "release" else "force_err_rel"
        for r in front:
            for o in sc["runs"]:
                if o is r or not o["stable"] or o["sweep"] == "direct-long-step":
                    continue
                assert not (o["cpu_s_per_sim_s"] < r["cpu_s_per_sim_s"] and o[key] < r[key])


def test_stability_quick_map():
    j = bench("stability", "--quick", "--random-steps", "3000")
    assert len(j["cells"]) == 16
    for c in j["cells"]:
        assert "non-finite" not in c.get("failure", ""), c["label"]
        # a blow-up at alpha < 1 switches the integrator to alpha 1 once and for all
        assert c["alpha_fallbacks"] <= 1, c["label"]
        if c["alpha"] == 1.0:
            assert c["max_kinetic_j"] <= c["energy_bound_j"], c["label"]
            assert c["restores"] == 0, c["label"]
            if c["dt_ms"] == 1.0:  # direct coupling at the haptic rate passes everything
                assert c["pass"], c
                assert c["max_penetration_mm"] <= 0.5, c
            elif c["contact_ticks"] > 0:
                # The multirate path, where its stroke touched the cloth: the cloth no more than
                # 2 mm inside the proxy. (With every contact's normal tilted by the proxy's whole
                # expected motion, the 20 ms stroke at 0.5 m/s rendered a drag several times its
                # normal force and read 2.86 mm: FingertipContact::place.)
                assert c["pass"], c
        elif c["restores"]:  # alpha 0.5 on the 1000x stiffer cloth blows up, then is damped
            assert c["alpha_fallbacks"] == 1 and c["stiffness_scale"] >= 100, c
    for r in j["random"]:
        assert "non-finite" not in r.get("failure", "")
        # no cloth point more than 0.5 mm inside a fingertip sphere, checked on every step
        assert r["max_penetration_mm"] <= 0.5, r
        assert r["contact_ticks"] > 0
        assert r["max_kinetic_j"] <= r["energy_bound_j"]
        assert r["restores"] == 0


def test_late_ticks():
    """hapticloth-bench late-ticks: with ticks 1-20 ms late in the press, the stroke and the
    pinch, the coupling gives the hand no energy beyond passivity (<= 1 mJ) and no force step
    (<= 2x the largest tick-to-tick change on time); the catch-up and the passivity controller
    are what keeps it so (without them the stroke 20 ms late gives 10x more energy, and the
    pinch 20 ms late a 2.6x larger step)."""
    j = bench("late-ticks")
    assert [c["late_ms"] for c in j["cases"]] == [1.0, 2.0, 5.0, 10.0, 20.0] * 3
    assert {c["name"] for c in j["cases"]} == {"press", "stroke", "pinch"}
    for c in j["cases"]:
        assert c["late_ticks"] == j["late_ticks_per_case"], c
        assert c["injected_energy_j"] <= 1e-3, c
        assert c["max_force_jump_n"] <= 2.0 * c["on_time_max_force_jump_n"], c
        assert c["on_time_max_force_jump_n"] > 0.0, c
        # No more than without the guards, to within the passivity controller's deadband (1 uJ:
        # deficits under it are left alone by design, haptics/loop/passivity.hpp)
        assert c["injected_energy_j"] <= c["unguarded"]["injected_energy_j"] + 1e-6, c
    stroke20 = next(c for c in j["cases"] if c["name"] == "stroke" and c["late_ms"] == 20.0)
    assert stroke20["unguarded"]["injected_energy_j"] > 5.0 * stroke20["injected_energy_j"]
    pinch20 = next(c for c in j["cases"] if c["name"] == "pinch" and c["late_ms"] == 20.0)
    # 0.092 N against 0.035 N with the pinch refined under the fingertips (the compliance in
    # series softens both); 9x before the main job refined by default
    assert pinch20["unguarded"]["max_force_jump_n"] > 2.0 * pinch20["max_force_jump_n"]


def test_tactile():
    """hapticloth-bench tactile (issue 37, point 6): every shipped material, both directions, 20
    to 200 mm/s. The vibration peaks at v / lambda within 2% or one bin; its third-octave bands
    from 20 to 400 Hz are within 1.6 dB of the surface model's; a still press gives nothing."""
    j = bench("tactile", timeout=300)
    assert len(j["cases"]) == 5 * 2 * 4
    assert {c["speed_m_s"] for c in j["cases"]} == {0.02, 0.05, 0.1, 0.2}
    for c in j["cases"]:
        assert abs(c["peak_hz"] - c["expected_hz"]) <= max(0.02 * c["expected_hz"], c["bin_hz"]), c
        assert c["band_error_db_max"] <= 1.6, c
    assert j["still_rms"] == 0.0


def test_haptic_subscribers():
    """hapticloth-bench haptic --subscribers: 3 alternating off/on pairs of server runs in a
    network namespace, each with the platform timer beside; every subscriber, over zenoh and
    over LCM, receives the server's messages. (The figure itself, the period error with and
    without subscribers, is a benchmark's: BENCHMARKS.md.)"""
    if os.geteuid() != 0 or not shutil.which("unshare"):
        pytest.skip("needs root and unshare for the network namespace")
    j = bench("haptic", "--subscribers", "2", "--duration", "2", timeout=300)
    assert j["subscribers"] == 2 and j["zenoh_subscribers"] == 1 and j["lcm_subscribers"] == 1
    assert len(j["pairs"]) == 3
    assert [list(p)[:2] for p in j["pairs"]] == [["off", "on"], ["on", "off"], ["off", "on"]]
    for p in j["pairs"]:
        assert p["off"]["received"] == []
        got = {r["transport"]: r["messages"] for r in p["on"]["received"]}
        # 2 s at a 120 Hz cloth rate, plus the haptics, stats and events topics
        assert got["zenoh"] > 200 and got["lcm"] > 200, p["on"]["received"]
        # Each run held its 2 s session. How closely the loop kept its 1 kHz is the benchmark's
        # figure, beside the platform timer's (BENCHMARKS.md): a fresh-clone CI run once saw 1763
        # ticks in a run on a day this VM woke threads up to 8-15 ms late.
        for run in (p["off"], p["on"]):
            assert run["ticks"] >= 1500
        assert p["platform_timer"]["ticks"] == 2000


def test_transport():
    """hapticloth-bench transport: the cloth state of the 968-triangle square over real zenoh and
    LCM on loopback, paced through the Hub (latency) and in a tight loop (throughput). Every
    state the Hub published reaches the subscriber, and the tight loop's states do too (the raw
    publisher used to stop at its first message, its refinement counts never set). The
    latencies themselves are a benchmark's (BENCHMARKS.md)."""
    if os.geteuid() != 0 or not shutil.which("unshare"):
        pytest.skip("needs root and unshare for LCM's network namespace")
    j = bench("transport", "--seconds", "1", timeout=300)
    for t in ("zenoh", "lcm"):
        lat, thr = j[t]["latency"], j[t]["throughput"]
        assert lat["sent"] > 500 and lat["received"] == lat["sent"], (t, lat)
        assert lat["bytes_per_message"] == thr["bytes_per_message"] > 529 * 12, (t, thr)
        assert 0 <= lat["latency_p50_us"] <= lat["latency_p99_us"], (t, lat)
        assert "platform_timer" in lat, t  # the figure beside the platform's own
        # The tight loop runs (how much of it a Python subscriber keeps up with is a figure: 88-99%)
        assert thr["sent"] > lat["sent"] and 0 < thr["received"] <= thr["sent"], (t, thr)


def test_haptic_subscribers_bad_input():
    r = subprocess.run([str(program("hapticloth-bench")), "haptic", "--subscribers", "0", "--json"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "--subscribers: must be a number of subscribers from 1 to 16, not 0" in r.stderr
    assert "Traceback" not in r.stderr


def test_step_preconditioners():
    """The step benchmark names the preconditioner it ran, and SSOR needs fewer iterations than
    block-Jacobi on the same release (the count, not the time, is asserted)."""
    runs = {p: bench("step", "--scene", str(SCENE), "--steps", "200", "--pcg-preconditioner", p)
            for p in ("ssor", "block-jacobi")}
    for p, j in runs.items():
        assert j["preconditioner"] == p
        assert j["finite"] and j["events"]["solver_not_converged"] == 0
    assert runs["ssor"]["solver_iterations_mean"] < 0.7 * runs["block-jacobi"]["solver_iterations_mean"]
    # The same cloth either way: both solves meet the same tolerance.
    assert abs(runs["ssor"]["lowest_vertex_height_m"] - runs["block-jacobi"]["lowest_vertex_height_m"]) < 1e-4


def test_step_pinch_of_a_settled_cloth():
    """--settle brings the hanging square to rest before the pinch, as the haptic scenes'
    preroll does: the fingertips then close across the hanging cloth (along y, not the level
    start's z), and a cloth at rest takes fewer solver iterations and re-solves a step than the
    one pinched as it falls from level. Both pinches hold the cloth outside the fingertips."""
    falling = bench("step", "--scene", str(SCENE), "--pinch", "--steps", "300")
    settled = bench("step", "--scene", str(SCENE), "--pinch", "--settle", "3", "--steps", "300")
    assert falling["settled_s"] == 0.0 and settled["settled_s"] == 3.0
    assert falling["pinch_across"] == [0.0, 0.0, 1.0]
    assert abs(settled["pinch_across"][1]) > 0.99
    for j in (falling, settled):
        assert j["both_fingers_in_contact"] > 0.95
        assert j["max_penetration_mm"] < 0.5
    assert settled["solver_iterations_per_step"]["mean"] < 0.7 * falling["solver_iterations_per_step"]["mean"]
    assert settled["solves_per_step"] < falling["solves_per_step"]
    # 968 triangles step on one thread (under kMinParallelElements): no helper to wait for.
    assert settled["helper_wait_us"] == {"p50": 0.0, "p99": 0.0, "steps_over_100us": 0.0}


def test_step_pinch_keeps_its_matrix():
    """The pinch of a cloth at rest (6 s, the haptic scenes' preroll) keeps its matrix from step to step (integrator.matrix_refresh): a few
    elements a step are formed anew and the solver reloads a few rows, where --matrix-refresh 0
    forms every element every step; the pinch is the same (its depth, its contact, its solver
    iterations)."""
    kept = bench("step", "--scene", str(SCENE), "--pinch", "--settle", "6", "--steps", "300")
    whole = bench("step", "--scene", str(SCENE), "--pinch", "--settle", "6", "--steps", "300",
                  "--matrix-refresh", "0")
    triangles = kept["triangles"]
    assert kept["kept_matrix"]["matrix_refresh"] == 1e-4
    assert kept["kept_matrix"]["elements_formed_per_step"] < 0.05 * triangles
    assert kept["kept_matrix"]["steps_formed_whole"] < 0.01
    assert 0 < kept["kept_matrix"]["rows_reloaded_p50"] < 0.1 * triangles
    assert whole["kept_matrix"]["elements_formed_per_step"] == triangles
    assert whole["kept_matrix"]["steps_formed_whole"] == 1.0
    assert abs(kept["max_penetration_mm"] - whole["max_penetration_mm"]) < 0.01 * whole["max_penetration_mm"]
    assert kept["both_fingers_in_contact"] == whole["both_fingers_in_contact"]
    assert abs(kept["solver_iterations_per_step"]["mean"] - whole["solver_iterations_per_step"]["mean"]) < \
        0.1 * whole["solver_iterations_per_step"]["mean"]


def test_step_script_times_the_step_by_fingers_in_contact():
    """--script plays the scene's [device] script (touch, stroke, pinch, lift, release) from the
    cloth at rest, directly coupled at 1 ms on the stepped clock, and splits the steps by how
    many fingertips touch the cloth: the script's first second touches nothing, finger 0 alone
    touches and strokes, and both hold the pinch from 5.8 s to 7.8 s."""
    j = bench("step", "--scene", str(SCENE), "--script")
    assert j["benchmark"] == "step-script" and j["settled_s"] == 6.0
    assert j["script"].endswith("touch_stroke_pinch.toml") and j["script_s"] == pytest.approx(8.4)
    by = j["fingers_in_contact"]
    steps = {k: by[k]["steps"] for k in ("none", "one", "both")}
    assert sum(steps.values()) == pytest.approx(1000 * j["script_s"], abs=2)
    assert steps["none"] > 1000 and steps["one"] > 1000 and 1500 < steps["both"] < 2500
    for k in ("none", "one", "both"):
        s = by[k]
        assert 0 < s["sim_step_us"]["p50"] <= s["sim_step_us"]["p99"] <= s["sim_step_us"]["max"]
        assert s["integrator_us"]["p50"] <= s["sim_step_us"]["p50"]
        assert s["iterations_per_step"]["mean"] > 0
    # A stroke's friction and the pinch's new contacts are solved again within their steps; an
    # untouched cloth never is.
    assert by["none"]["solves_per_step"] < 1.01 < by["one"]["solves_per_step"]
    # The pinch lifts the cloth, whose elements then move past the kept matrix's tolerance; at
    # rest between the touches few do.
    assert by["both"]["elements_formed_per_step"] > 2 * by["none"]["elements_formed_per_step"]
    assert j["max_penetration_mm"] < 0.5


def test_step_script_needs_a_device_script():
    r = subprocess.run([str(program("hapticloth-bench")), "step", "--scene",
                        str(SCENE.parent / "hanging_square_4k.toml"), "--script", "--json"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "step --script: scene 'hanging_square_4k' has no [device] script" in r.stderr
    r = subprocess.run([str(program("hapticloth-bench")), "step", "--scene", str(SCENE), "--script", "--pinch",
                        "--json"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "--pinch excludes --script" in r.stderr
    assert "Traceback" not in r.stderr


def test_step_bad_settle():
    def run(*args):
        return subprocess.run([str(program("hapticloth-bench")), "step", "--scene", str(SCENE), *args, "--json"],
                              capture_output=True, text=True, timeout=60)
    r = run("--pinch", "--settle", "-1")
    assert r.returncode != 0 and "--settle: must be >= 0 and <= 60, not -1" in r.stderr
    r = run("--settle", "3")
    assert r.returncode != 0 and "--settle requires --pinch" in r.stderr
    for r in (run("--pinch", "--settle", "-1"), run("--settle", "3")):
        assert "Traceback" not in r.stderr


@pytest.mark.parametrize("flag,value", [("--pcg-omega", "2.5"), ("--pcg-preconditioner", "ilu"),
                                        ("--matrix-refresh", "1.5")])
def test_step_bad_solver_flags(flag, value):
    r = subprocess.run([str(program("hapticloth-bench")), "step", "--scene", str(SCENE), flag, value, "--json"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert flag in r.stderr and value in r.stderr
    assert "Traceback" not in r.stderr


def test_limit_quick():
    j = bench("limit", "--quick")
    assert [r["scene"] for r in j["rows"]] == ["hanging_square", "hanging_square_4k", "hanging_square_16k"]
    flops = [r["cholmod_simplicial"]["flops"] for r in j["rows"]]
    assert all(f > 0 for f in flops) and flops == sorted(flops)
    for r in j["rows"]:
        assert r["cholmod_simplicial"]["ok"] and r["cholmod_supernodal"]["ok"]
        assert r["cholmod_simplicial"]["nnz_L"] >= r["nnz_A"] / 2


def cpu_has(flag: str) -> bool:
    return flag in Path("/proc/cpuinfo").read_text().split()


# The features of each level as server/cloth/simd_level.cpp asks the CPU for them (the psABI's
# x86-64-v3 and -v4), by their /proc/cpuinfo names.
V3 = ["avx2", "fma", "bmi1", "bmi2", "movbe", "f16c"]
LEVEL_FLAGS = {"baseline": [], "avx2": V3, "avx512": V3 + ["avx512f", "avx512bw", "avx512dq", "avx512vl", "avx512cd"]}


def test_step_names_its_level_and_every_level_steps_the_same_cloth():
    """`step --simd LEVEL` runs the element pass at that level (its lanes in the JSON), the default
    is the widest level the CPU has, and every level gives the same cloth to the last bit (the
    level units are compiled without FMA contraction: docs/performance.md)."""
    here = [lv for lv, flags in LEVEL_FLAGS.items() if all(cpu_has(f) for f in flags)]
    default = bench("step", "--scene", str(SCENE), "--steps", "200")
    assert default["simd"] == here[-1]
    lowest = {}
    for lv in here:
        j = bench("step", "--scene", str(SCENE), "--steps", "200", "--simd", lv)
        assert j["simd"] == lv and j["lanes"] == {"baseline": 2, "avx2": 4, "avx512": 8}[lv]
        lowest[lv] = j["lowest_vertex_height_m"]
    assert len(set(lowest.values())) == 1, lowest
    assert lowest[here[-1]] == default["lowest_vertex_height_m"]


def test_step_refuses_a_level_it_cannot_run():
    """An unknown level is refused by the option's check; a level the CPU lacks, with the CPU's
    own best level named (exit 2 either way, never SIGILL)."""
    r = subprocess.run([str(program("hapticloth-bench")), "step", "--scene", str(SCENE), "--simd", "sse9"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "--simd" in r.stderr, r.stderr
    lacking = [lv for lv, flags in LEVEL_FLAGS.items() if not all(cpu_has(f) for f in flags)]
    if not lacking:
        pytest.skip("this CPU runs every level")
    r = subprocess.run([str(program("hapticloth-bench")), "step", "--scene", str(SCENE), "--simd", lacking[0]],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "lacks" in r.stderr, r.stderr
