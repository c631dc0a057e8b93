#!/usr/bin/env python3
"""What local refinement under the fingertips costs, with it off and on, in one sitting.

Per haptic scene (the 968-, 4050- and 15842-triangle squares with their device scripts):
  - `hapticloth-bench step --script --refine off|on --json`: the scene's script played directly
    coupled at 1 kHz on the stepped clock, the children settled within each step (the step's
    whole cost: the cloth and the children);
  - `hapticloth-bench haptic --refine off|on --json`: the same in real time, the children settled
    beside the steps (what a session runs), the haptic loop's tick compute and missed deadlines
    beside the platform timer measured right after in the same invocation.
Prints one JSON object, or with --markdown the docs/contact.md table.

Usage: tools/bench/refine_cost.py [--bench build/hapticloth-bench] [--duration 10] [--markdown]
"""
import argparse
import json
import pathlib
import subprocess
import sys

from machine import cpu_model

TOP = pathlib.Path(__file__).resolve().parents[2]
SCENES = ["hanging_square.toml", "hanging_square_4k_haptic.toml", "hanging_square_16k_haptic.toml"]


def bench(exe, *args):
    cmd = [str(exe), *map(str, args), "--json"]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    if p.returncode != 0:
        sys.exit(f"refine_cost: {' '.join(cmd)} exited {p.returncode}: {p.stderr.strip()}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def measure(exe, scene, refine, duration):
    path = TOP / "tools/scenes" / scene
    step = bench(exe, "step", "--scene", path, "--script", "--refine", refine)
    rt = bench(exe, "haptic", "--scene", path, "--refine", refine, "--duration", duration)
    return {
        "triangles": step["triangles"],
        "stepped": {"sim_step_us": step["sim_step_us"], "refinement": step["refinement"]},
        "realtime": {k: rt.get(k) for k in ("sim_step_us", "compute_us", "missed_deadlines", "haptic_ticks",
                                            "cloth_time_ratio", "refinement_builds", "refinement_updates",
                                            "passivity_ticks", "energy_bound_ticks", "platform_timer")},
    }


def markdown(out):
    print(f"CPU: {out['cpu']}\n")
    print("| triangles | refine | stepped: sim step p50 / p99 | real time: sim step p50 / p99 | "
          "tick compute p99 | cloth / real time | children built | missed deadlines | "
          "platform wake-ups over 1 ms |")
    print("|---|---|---|---|---|---|---|---|---|")
    for scene, runs in out["scenes"].items():
        for refine, r in runs.items():
            s, t = r["stepped"]["sim_step_us"], r["realtime"]
            rs, cu, pt = t["sim_step_us"], t["compute_us"], t["platform_timer"]
            print(f"| {r['triangles']} | {refine} | {s['p50'] / 1e3:.2f} / {s['p99'] / 1e3:.2f} ms | "
                  f"{rs['p50'] / 1e3:.2f} / {rs['p99'] / 1e3:.2f} ms | {cu['p99']:.1f} us | "
                  f"{t['cloth_time_ratio']:.2f} | {t['refinement_builds']} | {t['missed_deadlines']} | "
                  f"{pt['over_1ms']} in {pt['ticks']} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default=str(TOP / "build/hapticloth-bench"))
    ap.add_argument("--duration", type=float, default=10.0, help="s of each real-time run (default 10)")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args()
    if not 0 < a.duration <= 3600:
        sys.exit("refine_cost: --duration must be in (0, 3600] s")
    out = {"cpu": cpu_model(), "duration_s": a.duration, "scenes": {}}
    for scene in SCENES:
        out["scenes"][scene] = {refine: measure(a.bench, scene, refine, a.duration) for refine in ("off", "on")}
    if a.markdown:
        markdown(out)
    else:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
