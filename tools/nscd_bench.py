"""NSCD throughput table for `make bench-nscd`.

Reads DIR/threads-T/run-K/summary.json (ballast-nscd runs of one scene preset) and
prints, per thread count, the median over the repeats of the NLGS throughput (contact
updates/s: Σ sweeps × contacts over the wall time of the "solve" phase) and of the four
phase times, with the throughput's ratio to the 1-thread runs of the same invocation and
to the figures of issue #5 (6.2e6 measured before this bench; target 3e7 per core).

    python tools/nscd_bench.py results/bench-nscd
"""

import json
import os
import statistics
import sys

PHASES = ("detect", "build", "solve", "update")
BEFORE = 6.2e6  # issue #5: contact updates/s measured before the NLGS work (1 thread)
TARGET = 3e7  # issue #5: contact updates/s per core


def runs(root):
    by_threads = {}
    for name in os.listdir(root):
        if not name.startswith("threads-"):
            continue
        for run in sorted(os.listdir(os.path.join(root, name))):
            path = os.path.join(root, name, run, "summary.json")
            if os.path.exists(path):
                with open(path) as f:
                    s = json.load(f)
                by_threads.setdefault(s["threads"], []).append(s)
    return dict(sorted(by_threads.items()))


def main(root):
    table = runs(root)
    if not table:
        sys.exit(f"nscd_bench: no summary.json under {root}")
    rows = {}
    for threads, summaries in table.items():
        med = lambda xs: statistics.median(xs)
        rows[threads] = {
            "n": len(summaries),
            "tput": med([s["figures"]["contact_updates_per_s"] for s in summaries]),
            "spread": (
                min(s["figures"]["contact_updates_per_s"] for s in summaries),
                max(s["figures"]["contact_updates_per_s"] for s in summaries),
            ),
            "phases": [med([s["wall_time_s"].get(p, 0.0) for s in summaries]) for p in PHASES],
            "contacts": med([s["figures"]["mean_contacts"] for s in summaries]),
            "sweeps": med([s["figures"]["mean_sweeps"] for s in summaries]),
            "steps": summaries[0]["figures"]["steps"],
        }
    first = table[next(iter(table))][0]
    base = rows[min(rows)]["tput"]
    print(
        f"NSCD bench: {first['scene']} --preset {first.get('preset') or '(none)'}, "
        f"{rows[min(rows)]['steps']} steps; medians of {rows[min(rows)]['n']} runs"
    )
    print()
    print(
        "| threads | mean contacts | mean sweeps | contact updates/s | (min – max) "
        "| vs 1 thread | vs 6.2e6 | vs 3e7 | detect s | build s | solve s | update s |"
    )
    print("|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for threads, r in rows.items():
        lo, hi = r["spread"]
        phases = " | ".join(f"{t:.3f}" for t in r["phases"])
        print(
            f"| {threads} | {r['contacts']:.0f} | {r['sweeps']:.1f} | {r['tput']:.3e} "
            f"| {lo:.2e} – {hi:.2e} | {r['tput'] / base:.2f} | {r['tput'] / BEFORE:.2f} "
            f"| {r['tput'] / TARGET:.2f} | {phases} |"
        )
    print()
    print(
        "Contact update = one local solve of one contact in one sweep; the solve phase "
        "includes the error measure after every sweep. The NLGS is sequential (more "
        "threads only speed up detection)."
    )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/bench-nscd")
