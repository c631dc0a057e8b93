#!/usr/bin/env python3
"""The cloth step at every instruction level this CPU runs, in one sitting.

Runs `hapticloth-bench step --simd LEVEL --json` on the 968-, 4050- and 15842-triangle squares,
the levels interleaved round by round (so that a slow spell of the machine falls on every level
alike), and prints one JSON object: the CPU, then per scene and level the medians over the rounds
of the step's median, p99 and assembly median, and the lowest vertex (which must be the same at
every level). --markdown prints the BENCHMARKS.md table instead.

Usage: tools/bench/simd_levels.py [--bench build/hapticloth-bench] [--rounds 3] [--markdown]
"""
import argparse
import json
import pathlib
import statistics
import subprocess
import sys

from machine import cpu_model

TOP = pathlib.Path(__file__).resolve().parents[2]
SCENES = [("hanging_square.toml", 1000), ("hanging_square_4k.toml", 1000), ("hanging_square_16k.toml", 400)]
LEVELS = ["baseline", "avx2", "avx512"]


def run(bench, scene, steps, level):
    cmd = [str(bench), "step", "--scene", str(TOP / "tools/scenes" / scene), "--steps", str(steps), "--json",
           "--simd", level]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode == 2 and "lacks" in p.stderr:
        return None  # the CPU lacks the level
    if p.returncode != 0:
        sys.exit(f"simd_levels: {' '.join(cmd)} exited {p.returncode}: {p.stderr.strip()}")
    return json.loads(p.stdout)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default=str(TOP / "build/hapticloth-bench"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args()
    if a.rounds < 1:
        sys.exit("simd_levels: --rounds must be at least 1")
    out = {"cpu": cpu_model(), "rounds": a.rounds, "scenes": {}}
    for scene, steps in SCENES:
        runs = {lv: [] for lv in LEVELS}
        for _ in range(a.rounds):
            for lv in LEVELS:
                r = run(a.bench, scene, steps, lv)
                if r is not None:
                    runs[lv].append(r)
        res = {}
        for lv, rs in runs.items():
            if not rs:
                continue
            res[lv] = {
                "lanes": rs[0]["lanes"],
                "triangles": rs[0]["triangles"],
                "steps": steps,
                "step_ms_median": statistics.median(r["ms_per_step_median"] for r in rs),
                "step_ms_p99": statistics.median(r["ms_per_step_p99"] for r in rs),
                "assemble_ms_median": statistics.median(r["assemble_ms_median"] for r in rs),
                "lowest_vertex_height_m": sorted({r["lowest_vertex_height_m"] for r in rs}),
            }
        out["scenes"][scene] = res
    if not a.markdown:
        print(json.dumps(out, indent=1))
        return
    print(f"CPU: {out['cpu']}; medians over {a.rounds} interleaved rounds.\n")
    print("| scene | level (lanes) | step median | step p99 | assembly median | lowest vertex |")
    print("|---|---|---|---|---|---|")
    for scene, res in out["scenes"].items():
        for lv, r in res.items():
            low = ", ".join(repr(v) for v in r["lowest_vertex_height_m"])
            print(f"| {r['triangles']} triangles | {lv} ({r['lanes']}) | {r['step_ms_median']:.3f} ms | "
                  f"{r['step_ms_p99']:.3f} ms | {r['assemble_ms_median']:.3f} ms | {low} m |")


if __name__ == "__main__":
    main()
