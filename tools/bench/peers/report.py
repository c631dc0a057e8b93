#!/usr/bin/env python3
"""Combine the per-simulator JSON files of tools/bench/peers/run into one object and print the
markdown table.

Usage: report.py [--print table|json] [--commit REV] OUT.json IN.json [IN.json ...]
--print json prints the combined object (one line) instead of the table; --commit names the
server's commit in it. An input that is missing or not JSON (a script that failed) becomes an error row.
"""

import argparse
import json
import os
import platform
import sys
import time


def fmt(x, digits=3):
    if x is None:
        return "-"
    if x >= 100:
        return f"{x:.0f}"
    return f"{x:.{digits}g}"


def run_at(runs, dt_ms):
    for r in runs:
        if dt_ms is not None and abs(r.get("dt_ms", -1) - dt_ms) < 1e-9:
            return r
    return None


def cpu_cell(r):
    if r is None:
        return "-"
    v = r.get("cpu_s_per_sim_s")
    if not r.get("stable"):
        return f"({fmt(v)}, unstable)" if v is not None else "unstable"
    return fmt(v) + ("*" if r.get("truncated") else "")


def dt_cell(res):
    runs = res.get("runs") or []
    best = res.get("largest_stable_dt_ms")
    if res.get("error") and not runs:
        return "not run"
    if best is None:
        smallest = min((r["dt_ms"] for r in runs), default=None)
        return f"< {fmt(smallest)} ms" if smallest is not None else "-"
    top = max(r["dt_ms"] for r in runs)
    return f"{fmt(best)} ms" + (" (largest tried)" if best == top else "")


def notes_cell(res):
    parts = [res.get("notes", "")]
    trunc = [r for r in res.get("runs") or [] if r.get("truncated")]
    if trunc:
        parts.append("wall cap: " + ", ".join(f"{fmt(r['dt_ms'])} ms ran {fmt(r.get('simulated_s'))} s"
                                             for r in trunc))
    best = res.get("largest_stable_dt_ms")
    r = run_at(res.get("runs") or [], best)
    if r is not None:
        notable = []
        if (r.get("max_stretch") or 0) >= 0.05:
            notable.append(f"max edge stretch {100 * r['max_stretch']:.0f}%")
        if (r.get("max_kinetic_energy_j") or 0) >= 0.4:
            notable.append(f"max kinetic energy {r['max_kinetic_energy_j']:.2g} J")
        if notable:
            parts.append(f"at {fmt(best)} ms: " + ", ".join(notable))
    first_bad = next((r for r in sorted(res.get("runs") or [], key=lambda r: r["dt_ms"])
                      if not r.get("stable")), None)
    if first_bad is not None:
        parts.append(f"at {fmt(first_bad['dt_ms'])} ms: {first_bad.get('reason', '')}")
    if res.get("error"):
        parts.append("error: " + res["error"])
    return "; ".join(p for p in parts if p).replace("|", "/")


def print_table(rows):
    print("| simulator / solver | version | model mapping | largest stable dt |"
          " CPU s per sim s at 1 ms | CPU s per sim s at largest stable dt | notes |")
    print("|---|---|---|---|---|---|---|")
    for res in rows:
        runs = res.get("runs") or []
        name = f"{res.get('simulator', '')} {res.get('variant', '')}".strip()
        print(f"| {name} | {res.get('version', '')} | {res.get('mapping_short', res.get('mapping', ''))} |"
              f" {dt_cell(res)} | {cpu_cell(run_at(runs, 1.0))} |"
              f" {cpu_cell(run_at(runs, res.get('largest_stable_dt_ms')))} | {notes_cell(res)} |")
    print()
    print("CPU s per sim s: CPU seconds spent stepping per simulated second (single thread)."
          " * = the run hit the wall-time cap before the end; the figure is from the part it ran."
          " (x, unstable) = CPU rate until the run failed.")


def main():
    ap = argparse.ArgumentParser(description="Combine the peers' JSON and print it or its table.")
    ap.add_argument("--print", choices=("table", "json"), default="table")
    ap.add_argument("--commit", default="unknown", help="the server's commit")
    ap.add_argument("out_path")
    ap.add_argument("inputs", nargs="+")
    a = ap.parse_args()
    out_path, inputs = a.out_path, a.inputs
    sources, rows = [], []
    for path in inputs:
        name = os.path.splitext(os.path.basename(path))[0]
        try:
            with open(path) as f:
                lines = [ln for ln in f.read().splitlines() if ln.startswith("{")]
            d = json.loads(lines[-1])
        except Exception as e:
            d = {"simulator": name, "version": "?", "results": [{
                "simulator": name, "variant": "", "version": "?", "mapping": "", "runs": [],
                "largest_stable_dt_ms": None,
                "error": f"no result ({type(e).__name__}); see {os.path.splitext(path)[0]}.log"}]}
        sources.append(d)
        rows.extend(d.get("results", []))
    combined = {
        "scene": "tools/scenes/hanging_square.toml (0.5 m square, 529 vertices, 968 triangles, top row pinned)",
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "commit": a.commit,
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "python": platform.python_version()},
        "cpu_time": "time.process_time of the stepping only (checks excluded), single thread; "
                    "ours: the server process's CPU time less its start-up",
        "results": rows,
    }
    if sources and "criteria" in sources[0]:
        combined["criteria"] = sources[0]["criteria"]
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    with open(out_path, "w") as f:
        json.dump(combined, f, indent=1)

    if a.print == "json":
        print(json.dumps(combined))
    else:
        print_table(rows)


if __name__ == "__main__":
    main()
