"""NSCD throughput table for `make bench-nscd`.

Reads DIR/<case>/run-K/summary.json (ballast-nscd runs of scenes/drop_box.toml) and
prints, per case, the median over the repeats of the NLGS throughput (contact
updates/s: Σ sweeps × contacts over the wall time of the "solve" phase, which includes
the set-up and the error measures), the same per core, and the four phase times; ratios
against the portable kernel's 1-thread run, against the 1-thread run of the same preset,
and against issue #5's figures (6.2e6 measured before any of this work; target 3e7 per
core).

    python tools/nscd_bench.py results/bench-nscd
"""

import json
import os
import statistics
import sys

PHASES = ("detect", "build", "solve", "update")
BEFORE = 6.2e6  # issue #5: contact updates/s measured before the NLGS work (1 thread)
TARGET = 3e7  # issue #5: contact updates/s per core


def cases(root):
    table = {}
    for name in sorted(os.listdir(root)):
        if not os.path.isdir(os.path.join(root, name)):
            continue
        runs = []
        for run in sorted(os.listdir(os.path.join(root, name))):
            path = os.path.join(root, name, run, "summary.json")
            if os.path.exists(path):
                with open(path) as f:
                    runs.append(json.load(f))
        if runs:
            table[name] = runs
    return table


def main(root):
    table = cases(root)
    if not table:
        sys.exit(f"nscd_bench: no summary.json under {root}")
    med = statistics.median
    rows = {}
    for name, runs in table.items():
        tputs = [s["figures"]["contact_updates_per_s"] for s in runs]
        wall = runs[0]["wall_time_s"]
        rows[name] = {
            "n": len(runs),
            "preset": runs[0].get("preset") or "(none)",
            "threads": runs[0]["threads"],
            "kernel": runs[0]["figures"].get("kernel", "?"),
            "driver": "DDM sync" if "solve: subdomains (parallel)" in wall else "sequential",
            "tput": med(tputs),
            "spread": (min(tputs), max(tputs)),
            "phases": [med([s["wall_time_s"].get(p, 0.0) for s in runs]) for p in PHASES],
            "contacts": med([s["figures"]["mean_contacts"] for s in runs]),
            "sweeps": med([s["figures"]["mean_sweeps"] for s in runs]),
            "steps": runs[0]["figures"]["steps"],
        }
    portable = next((r for r in rows.values() if r["kernel"] == "portable"), None)
    n = min(r["n"] for r in rows.values())
    print(f"NSCD bench: scenes/drop_box.toml, {next(iter(rows.values()))['steps']} steps; "
          f"medians of {n} runs (min – max)\n")
    print(
        "| preset | kernel | NLGS | threads | mean contacts | mean sweeps | contact updates/s "
        "| (min – max) | per core | vs portable | vs 1 thread | vs 6.2e6 | per core vs 3e7 "
        "| detect s | build s | solve s | update s |"
    )
    print("|---|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    order = sorted(rows.values(), key=lambda r: (r["preset"], r["threads"], r["kernel"] == "portable"))
    for r in order:
        lo, hi = r["spread"]
        per_core = r["tput"] / r["threads"]
        one = next((o for o in rows.values() if o["preset"] == r["preset"]
                    and o["threads"] == 1 and o["kernel"] == r["kernel"]), None)
        vs_one = f"{r['tput'] / one['tput']:.2f}" if one else "–"
        vs_portable = f"{r['tput'] / portable['tput']:.2f}" if portable else "–"
        phases = " | ".join(f"{t:.3f}" for t in r["phases"])
        print(
            f"| {r['preset']} | {r['kernel']} | {r['driver']} | {r['threads']} "
            f"| {r['contacts']:.0f} | {r['sweeps']:.1f} | {r['tput']:.3e} | {lo:.2e} – {hi:.2e} "
            f"| {per_core:.3e} | {vs_portable} | {vs_one} | {r['tput'] / BEFORE:.2f} "
            f"| {per_core / TARGET:.2f} | {phases} |"
        )
    print()
    print(
        "Contact update = one local solve of one contact in one sweep, with the velocity "
        "update of its two bodies. The solve phase includes the set-up and the error "
        "measures (every 10 sweeps). On 2 threads the NLGS is the synchronous DDM "
        "(two slabs, subdomains in parallel, then the interface)."
    )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/bench-nscd")
