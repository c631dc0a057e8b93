#!/usr/bin/env python3
"""The hanging square in our own server, headless, over the same dt list as the peers.

Runs build/hapticloth-server --scene tools/scenes/hanging_square.toml --headless --duration T
--dt DT --json (with --solver pcg and --solver cholmod) once per dt. CPU time is the child
process's user + system time (getrusage) less the CPU time of a one-step run (start-up: reading
the scene and building the model, ~10 ms, the least of three), so that, as for the peers, only the
stepping is counted; the summary's wall time of the stepping loop is recorded beside it.

Stability, from what the summary gives: the state is finite, the integrator counted no non-finite
state, energy explosion, restore or retry (a retry halves dt for that step, so the run would not
be at its nominal dt), the final kinetic energy is below the same bound as the peers', and the lowest
vertex at the end is in [-0.65, -0.45] m. The summary has no edge stretch and no intermediate
checks.
"""

import common  # noqa: I001  (scene constants and criteria; sets the thread variables)

import json
import os
import resource
import subprocess
import sys

TOP = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
SERVER = os.environ.get("HAPTICLOTH_SERVER", os.path.join(TOP, "build", "hapticloth-server"))
SCENE = os.path.join(TOP, "tools", "scenes", "hanging_square.toml")


def server(solver, dt, sim_time, timeout):
    """(completed process, child CPU s) of one headless run."""
    cmd = [SERVER, "--scene", SCENE, "--headless", "--duration", f"{sim_time:g}", "--dt", f"{dt:g}",
           "--json", "--solver", solver, "--no-zenoh", "--no-lcm-log", "--no-realtime"]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cp = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return cp, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def startup_cpu(solver):
    return min(server(solver, 1e-3, 1e-3, 60)[1] for _ in range(3))


def run_one(solver, dt, sim_time, wall_cap, startup):
    try:
        cp, cpu_raw = server(solver, dt, sim_time, max(wall_cap * 3, 60))
    except subprocess.TimeoutExpired:
        return {"dt_ms": dt * 1e3, "stable": False, "reason": "timed out", "truncated": True}
    except OSError as e:   # e.g. the binary is being rebuilt
        return {"dt_ms": dt * 1e3, "stable": False, "reason": f"could not run the server: {e}",
                "truncated": False}
    cpu = max(cpu_raw - startup, 0.0)
    lines = [ln for ln in cp.stdout.splitlines() if ln.startswith("{")]
    if cp.returncode != 0 or not lines:
        return {"dt_ms": dt * 1e3, "stable": False, "truncated": False, "cpu_s": round(cpu, 4),
                "reason": f"server exited {cp.returncode}: {(cp.stderr or cp.stdout)[-200:].strip()}"}
    s = json.loads(lines[-1])
    ev = s.get("events", {})
    reasons = []
    if not s.get("finite", False) or ev.get("non_finite", 0):
        reasons.append(f"non-finite ({ev.get('non_finite', 0)} events)")
    for key in ("energy_explosions", "restores", "retries", "solver_error"):
        if ev.get(key, 0):
            reasons.append(f"{ev[key]} {key.replace('_', ' ')}")
    ke = s.get("final_kinetic_energy_j", float("inf"))
    if not ke < common.KE_MAX:
        reasons.append(f"final kinetic energy {ke:.3g} J > {common.KE_MAX:.2f} J")
    low = s.get("lowest_vertex_height_m", float("nan"))
    if not (common.Z_LOW_MIN <= low <= common.Z_LOW_MAX):
        reasons.append(f"lowest vertex at {low:.3f} m, outside [{common.Z_LOW_MIN}, {common.Z_LOW_MAX}]")
    sim_s = s.get("simulated_s", 0.0)
    return {
        "dt_ms": dt * 1e3,
        "stable": not reasons,
        "reason": "; ".join(reasons),
        "truncated": False,
        "steps": s.get("steps"),
        "simulated_s": round(sim_s, 6),
        "cpu_s": round(cpu, 4),
        "cpu_s_raw": round(cpu_raw, 4),
        "startup_cpu_s": round(startup, 4),
        "wall_s": round(s.get("wall_s", 0.0), 4),
        "cpu_s_per_sim_s": round(cpu / sim_s, 4) if sim_s > 0 else None,
        "step_wall_s_per_sim_s": round(s.get("wall_s", 0.0) / sim_s, 4) if sim_s > 0 else None,
        "final_lowest_z_m": round(low, 4),
        "max_stretch": None,
        "final_kinetic_energy_j": ke,
        "solver_iterations_mean": s.get("solver_iterations_mean"),
        "events": ev,
    }


def server_version():
    try:
        out = subprocess.run(["git", "-C", TOP, "describe", "--always", "--dirty"], capture_output=True,
                             text=True, timeout=10).stdout.strip()
        return f"hapticloth {out}" if out else "hapticloth"
    except Exception:
        return "hapticloth"


def main():
    args = common.parser(__doc__.splitlines()[1]).parse_args()
    dts = [float(x) for x in args.dts.split(",") if x.strip()]
    only = {x.strip() for x in args.only.split(",") if x.strip()}
    mapping = ("HAPTEX membrane: measured nonlinear weft/warp/shear curves of 11 oz denim"
               f" (small strain {common.K_WEFT:g} / {common.K_WARP:g} / {common.K_SHEAR:g} N/m),"
               " lumped mass, air damping 0.5 N s/m^3; implicit Euler (alpha 1)")
    results = []
    for solver, notes in (("pcg", "one linearized implicit solve per step (eq. 9) by PCG (float matrix, the scene's tolerance 1e-3)"),
                          ("cholmod", "one linearized implicit solve per step (eq. 9) by sparse Cholesky (CHOLMOD)")):
        if only and solver not in only:
            continue
        common.log(f"ours {solver}")
        runs = []
        try:
            startup = startup_cpu(solver)
        except (OSError, subprocess.SubprocessError):
            startup = 0.0
        for dt_ms in dts:
            if not os.path.exists(SERVER):
                runs.append({"dt_ms": dt_ms, "stable": False, "reason": f"no server at {SERVER}"})
                continue
            r = run_one(solver, dt_ms * 1e-3, args.sim_time, args.wall_cap, startup)
            runs.append(r)
            common.log(f"  dt {dt_ms:g} ms: {'stable' if r['stable'] else 'UNSTABLE'}"
                       f" cpu/sim {r.get('cpu_s_per_sim_s')} low {r.get('final_lowest_z_m')} {r['reason']}")
        results.append({"simulator": "hapticloth (ours)", "variant": solver, "version": server_version(),
                        "mapping": mapping, "notes": notes, "sim_time_s": args.sim_time,
                        "mapping_short": (f"HAPTEX nonlinear curves, {common.K_WEFT:.0f} / {common.K_WARP:.0f}"
                                          f" / {common.K_SHEAR:.0f} N/m at zero strain"),
                        "runs": runs, "largest_stable_dt_ms": common.largest_stable_dt_ms(runs)})
    out = {"simulator": "hapticloth (ours)", "version": server_version(), "results": results}
    if args.json:
        print(json.dumps(out))
    else:
        for r in results:
            print(f"ours {r['variant']}: largest stable dt {r['largest_stable_dt_ms']} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
