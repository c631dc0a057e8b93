"""The hanging-square scene and the dt sweep shared by the peer scripts.

Scene (tools/scenes/hanging_square.toml): a 0.5 m x 0.5 m square, 22 x 22 quads (23 x 23 = 529
vertices, 968 triangles, neighbouring quads split along alternating diagonals as the server does),
flat at z = 0 with x, y in [-0.25, 0.25], the row y = +0.25 pinned, gravity (0, 0, -9.81), released
from rest. 11 oz denim: 0.324 kg/m^2; small-strain tension per unit strain 399.4 N/m weft (x),
2003.9 N/m warp (y), 53.4 N/m shear (per radian); air damping 0.5 N s/m^3 (velocities decay at
0.5 / 0.324 = 1.54 /s); no bending.

A peer script gives run_variants() its variants, each with a factory make(dt) -> object with
  step()            advance one time step of dt
  positions()       (n, 3) float array of the vertex positions, in the peer's own vertex order
and the sweep maps the peer's vertices onto the grid by their rest positions, times the steps with
time.process_time (checks excluded), and judges stability the same way for every peer.
"""

import os

for _v in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS",
           "VECLIB_MAXIMUM_THREADS"):
    os.environ[_v] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

# --- the scene ---------------------------------------------------------------------------------
SIZE = 0.5                      # m
QUADS = 22
N = QUADS + 1                   # vertices per side
H = SIZE / QUADS                # m, grid spacing
ORIGIN = (-0.25, -0.25, 0.0)
DENSITY = 0.324                 # kg/m^2
MASS = DENSITY * SIZE * SIZE    # 0.081 kg
GRAVITY = (0.0, 0.0, -9.81)
AIR_DAMPING = 0.5               # N s/m^3
AIR_DECAY = AIR_DAMPING / DENSITY   # 1/s: dv/dt = -AIR_DECAY v
K_WEFT = 399.4                  # N/m, sigma_uu / eps_uu at eps = 0 (tools/materials/denim-handmade.toml)
K_WARP = 2003.9                 # N/m
K_SHEAR = 53.4                  # N/m per radian of shear angle
# Isotropic peers get the warp value in every direction (the stiffest direction: it carries the
# hanging weight and sets the highest frequency, so the stability limit), with no Poisson coupling.
K_ISO = K_WARP

# --- stability criteria -------------------------------------------------------------------------
PE_RELEASED = MASS * 9.81 * SIZE / 2    # J: the centre of mass falls by 0.25 m (~0.2 J)
KE_MAX = 10.0 * PE_RELEASED             # J
Z_LOW_MIN, Z_LOW_MAX = -0.65, -0.45     # m, the lowest vertex at the end (see LAST_S)
# A peer without air damping (PyBullet) still swings at the end: the check takes the lowest vertex
# position reached over the last LAST_S of the run, which for a cloth at rest is its final value
# and for a swinging one the bottom of the swing.
LAST_S = 1.0
STRETCH_MAX = 0.5                       # largest edge strain allowed at any check
CHECK_EVERY_S = 0.01                    # s of simulated time between checks

DEFAULT_DTS_MS = [0.25, 0.5, 1, 2, 5, 10, 20, 40, 80]
DEFAULT_SIM_TIME = 3.0          # s
DEFAULT_WALL_CAP = 60.0         # s per run


def grid():
    """Vertices (N*N, 3), triangles (968, 3), pinned vertex ids, vertex index v = j*N + i."""
    i, j = np.meshgrid(np.arange(N), np.arange(N))          # j rows (y), i columns (x)
    x = ORIGIN[0] + H * i.ravel()
    y = ORIGIN[1] + H * j.ravel()
    verts = np.stack([x, y, np.zeros_like(x)], axis=1)
    tris = []
    for jj in range(QUADS):
        for ii in range(QUADS):
            p00, p10 = jj * N + ii, jj * N + ii + 1
            p01, p11 = (jj + 1) * N + ii, (jj + 1) * N + ii + 1
            if (ii + jj) % 2 == 0:
                tris += [(p00, p10, p11), (p00, p11, p01)]
            else:
                tris += [(p00, p10, p01), (p10, p11, p01)]
    tris = np.array(tris, dtype=np.int64)
    pinned = np.arange((N - 1) * N, N * N)                  # the row y = +0.25
    return verts, tris, pinned


def edges_of(tris):
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e.sort(axis=1)
    return np.unique(e, axis=0)


def lumped_masses(verts, tris):
    """A third of each triangle's mass to each of its vertices (as the server lumps)."""
    a = verts[tris[:, 1]] - verts[tris[:, 0]]
    b = verts[tris[:, 2]] - verts[tris[:, 0]]
    area = 0.5 * np.linalg.norm(np.cross(a, b), axis=1)
    m = np.zeros(len(verts))
    np.add.at(m, tris.ravel(), np.repeat(DENSITY * area / 3.0, 3))
    return m


VERTS, TRIS, PINNED = grid()
EDGES = edges_of(TRIS)
REST = np.linalg.norm(VERTS[EDGES[:, 1]] - VERTS[EDGES[:, 0]], axis=1)
MASSES = lumped_masses(VERTS, TRIS)
FREE = np.setdiff1d(np.arange(N * N), PINNED)


def write_obj(path, verts=VERTS, tris=TRIS):
    with open(path, "w") as f:
        f.write("# hanging square, 23 x 23 vertices\n")
        for v in verts:
            f.write(f"v {v[0]:.9f} {v[1]:.9f} {v[2]:.9f}\n")
        for t in tris:
            f.write(f"f {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")


def match_order(peer_rest):
    """perm such that peer_rest[perm[k]] is grid vertex k (matched by rest position)."""
    peer_rest = np.asarray(peer_rest, dtype=float)
    if peer_rest.shape != VERTS.shape:
        raise RuntimeError(f"peer has {peer_rest.shape[0]} vertices, the grid {VERTS.shape[0]}")
    d = np.linalg.norm(peer_rest[None, :, :2] - VERTS[:, None, :2], axis=2)
    perm = d.argmin(axis=1)
    if d[np.arange(len(perm)), perm].max() > 1e-4 or len(set(perm.tolist())) != len(perm):
        raise RuntimeError("peer vertices do not match the grid")
    return perm


def measure(x, x_prev, dt):
    """(finite, kinetic energy J, lowest z m, max edge strain) of grid-ordered positions."""
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(x_prev))):
        return False, math.inf, math.nan, math.inf
    v = (x - x_prev) / dt
    ke = 0.5 * float(np.sum(MASSES[:, None] * v * v))
    length = np.linalg.norm(x[EDGES[:, 1]] - x[EDGES[:, 0]], axis=1)
    stretch = float(np.max(length / REST - 1.0))
    return True, ke, float(x[:, 2].min()), stretch


def run_one(make_sim, dt, sim_time, wall_cap):
    sim = make_sim(dt)
    perm = match_order(sim.positions())
    steps = int(round(sim_time / dt))
    every = max(1, int(round(CHECK_EVERY_S / dt)))
    cpu = 0.0
    t_wall0 = time.monotonic()
    done = 0
    reason = ""
    max_ke, max_stretch, low = 0.0, 0.0, math.nan
    low_last = math.inf
    truncated = False
    error = None
    while done < steps:
        n = min(every, steps - done)
        try:
            c0 = time.process_time()
            for _ in range(n - 1):
                sim.step()
            cpu += time.process_time() - c0
            x_prev = np.asarray(sim.positions(), dtype=float)[perm]
            c0 = time.process_time()
            sim.step()
            cpu += time.process_time() - c0
        except Exception as e:  # a peer's solver may raise on divergence
            error = f"{type(e).__name__}: {str(e)[:160]}"
            reason = "solver error: " + error
            break
        done += n
        x = np.asarray(sim.positions(), dtype=float)[perm]
        ok, ke, low, stretch = measure(x, x_prev, dt)
        if not ok:
            reason = f"non-finite state at t = {done * dt:.3f} s"
            break
        max_ke = max(max_ke, ke)
        max_stretch = max(max_stretch, stretch)
        if done * dt >= sim_time - LAST_S - 1e-9:
            low_last = min(low_last, low)
        if ke > KE_MAX:
            reason = f"kinetic energy {ke:.3g} J > {KE_MAX:.2f} J at t = {done * dt:.3f} s"
            break
        if stretch > STRETCH_MAX:
            reason = f"edge stretch {100 * stretch:.0f}% > {100 * STRETCH_MAX:.0f}% at t = {done * dt:.3f} s"
            break
        if time.monotonic() - t_wall0 > wall_cap and done < steps:
            truncated = True
            break
    wall = time.monotonic() - t_wall0
    sim_done = done * dt
    if not reason and not truncated and not (Z_LOW_MIN <= low_last <= Z_LOW_MAX):
        reason = (f"lowest vertex over the last {LAST_S:g} s at {low_last:.3f} m,"
                  f" outside [{Z_LOW_MIN}, {Z_LOW_MAX}]")
    if hasattr(sim, "close"):
        sim.close()
    return {
        "dt_ms": dt * 1e3,
        "stable": not reason,
        "reason": reason or (f"truncated at {sim_done:.2f} s of {sim_time:g} s (wall cap): "
                             "no failure until then, lowest-vertex check skipped" if truncated else ""),
        "truncated": truncated,
        "steps": done,
        "simulated_s": round(sim_done, 6),
        "cpu_s": round(cpu, 4),
        "wall_s": round(wall, 3),
        "cpu_s_per_sim_s": round(cpu / sim_done, 4) if sim_done > 0 else None,
        "final_lowest_z_m": None if math.isnan(low) else round(low, 4),
        "lowest_z_last_s_m": None if math.isinf(low_last) else round(low_last, 4),
        "max_stretch": None if math.isinf(max_stretch) else round(max_stretch, 5),
        "max_kinetic_energy_j": round(max_ke, 5),
    }


def largest_stable_dt_ms(runs):
    best = None
    for r in sorted(runs, key=lambda r: r["dt_ms"]):
        if not r["stable"]:
            break
        best = r["dt_ms"]
    return best


def sweep(make_sim, dts_ms, sim_time, wall_cap, log=None):
    runs = []
    for dt_ms in dts_ms:
        r = run_one(make_sim, dt_ms * 1e-3, sim_time, wall_cap)
        runs.append(r)
        if log:
            log(f"  dt {dt_ms:g} ms: {'stable' if r['stable'] else 'UNSTABLE'}"
                f" cpu/sim {r['cpu_s_per_sim_s']} low {r['final_lowest_z_m']}"
                f" stretch {r['max_stretch']} {r['reason']}")
    return runs


def parser(description):
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--dts", default=",".join(f"{d:g}" for d in DEFAULT_DTS_MS),
                   help="time steps in ms, comma-separated")
    p.add_argument("--sim-time", type=float, default=DEFAULT_SIM_TIME, help="simulated s per run")
    p.add_argument("--wall-cap", type=float, default=DEFAULT_WALL_CAP,
                   help="stop a run after this many s of wall time")
    p.add_argument("--only", default="", help="comma-separated variant names to run (default all)")
    p.add_argument("--k-scale", type=float, default=1.0,
                   help="scale every stiffness (a calibration aid: softer cloth sags measurably)")
    return p


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run_variants(args, simulator, version, variants):
    """variants: list of dicts name, mapping, notes, make (dt -> sim); optional keys: error (the
    variant cannot run: say why), warmup (called once before its sweep), extra_dts_ms (added to the
    list), optional (run only when named with --only)."""
    dts = [float(s) for s in args.dts.split(",") if s.strip()]
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    results = []
    # Peers print warnings on stdout (fd 1): send them to stderr so stdout holds only the JSON.
    saved_stdout = os.dup(1)
    sys.stdout.flush()
    os.dup2(2, 1)
    try:
        _run(args, simulator, version, variants, dts, only, results)
    finally:
        sys.stdout.flush()
        os.dup2(saved_stdout, 1)
        os.close(saved_stdout)
    out = {"simulator": simulator, "version": version, "results": results,
           "criteria": {"ke_max_j": round(KE_MAX, 4), "lowest_z_m": [Z_LOW_MIN, Z_LOW_MAX],
                        "lowest_z_over_last_s": LAST_S,
                        "stretch_max": STRETCH_MAX, "check_every_s": CHECK_EVERY_S}}
    if args.json:
        print(json.dumps(out), flush=True)
    else:
        for r in results:
            print(f"{simulator} {r['variant']}: largest stable dt {r['largest_stable_dt_ms']} ms"
                  + (f" ({r['error']})" if r.get("error") else ""))
    return out


def _run(args, simulator, version, variants, dts, only, results):
    for v in variants:
        if (only and v["name"] not in only) or (not only and v.get("optional")):
            continue
        log(f"{simulator} {v['name']}")
        entry = {"simulator": simulator, "variant": v["name"], "version": version,
                 "mapping": v["mapping"], "mapping_short": v.get("short", v["mapping"]),
                 "notes": v.get("notes", ""),
                 "sim_time_s": args.sim_time, "wall_cap_s": args.wall_cap}
        if v.get("error"):
            entry.update(runs=[], largest_stable_dt_ms=None, error=v["error"])
        else:
            vdts = sorted(set(dts) | set(v.get("extra_dts_ms", [])))
            try:
                if v.get("warmup"):
                    v["warmup"]()
                entry["runs"] = sweep(v["make"], vdts, args.sim_time, args.wall_cap, log)
                entry["largest_stable_dt_ms"] = largest_stable_dt_ms(entry["runs"])
            except Exception as e:
                entry.update(runs=entry.get("runs", []), largest_stable_dt_ms=None,
                             error=f"{type(e).__name__}: {e}")
                log(f"  error: {entry['error']}")
        results.append(entry)
