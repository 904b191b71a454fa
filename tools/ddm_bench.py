"""DDM bench table for `make bench-ddm` (issue #7; seed 000 Tables 1 and 2).

Reads DIR/threads-T/run-K/summary.json and packing.toml (ballast-pack runs of one scene
preset with the synchronous DDM) and prints, per thread count, the medians over the
repeats of the phase times in the layout of the seed's Table 1 (contact detection; NLGS
solve split into the subdomains, run in parallel, and the interface, run sequentially;
other parts), then the speedup T1/Tp and efficiency Sp/p of the parallel part (the
subdomains) and of the whole stepping, as in its Table 2, against issue #7's target
(at least 85 % on 2 threads) and the seed's (63.3 % for the OpenMP part on 4 cores).
It fails when the packings differ between thread counts (the synchronous DDM must not
depend on them).

    python tools/ddm_bench.py results/bench-ddm
"""

import json
import os
import statistics
import sys

TARGET = 0.85  # issue #7: parallel part efficiency on 2 threads
SEED = 0.633  # seed 000 Table 2: OpenMP part, 4 cores, 7 subdomains


def load(root):
    runs = {}
    for name in sorted(os.listdir(root)):
        if not name.startswith("threads-"):
            continue
        for run in sorted(os.listdir(os.path.join(root, name))):
            d = os.path.join(root, name, run)
            with open(os.path.join(d, "summary.json")) as f:
                s = json.load(f)
            with open(os.path.join(d, "packing.toml"), "rb") as f:
                s["packing"] = f.read()
            runs.setdefault(s["figures"]["threads"], []).append(s)
    return dict(sorted(runs.items()))


def phases(s):
    w = s["wall_time_s"]
    sub = w.get("solve: subdomains (parallel)", 0.0)
    gamma = w.get("solve: interface (sequential)", 0.0)
    total = s["figures"]["stepping_s"]
    detect = w.get("detect", 0.0)
    rest_of_solve = w.get("solve", 0.0) - sub - gamma
    other = total - detect - sub - gamma - rest_of_solve
    return {
        "total": total,
        "detect": detect,
        "solve": w.get("solve", 0.0),
        "subdomains": sub,
        "interface": gamma,
        "solve_other": rest_of_solve,
        "other": other,
    }


def main(root):
    runs = load(root)
    if not runs:
        sys.exit(f"ddm_bench: no runs under {root}")
    packings = {s["packing"] for r in runs.values() for s in r}
    if len(packings) != 1:
        sys.exit("ddm_bench: the packings differ between thread counts")
    med = {t: {k: statistics.median(phases(s)[k] for s in r) for k in phases(r[0])}
           for t, r in runs.items()}
    first = next(iter(runs.values()))[0]
    f = first["figures"]
    print(
        f"DDM bench: {first['scene']} --preset {first.get('preset')}, {f['grains']} stones, "
        f"{f['steps']} steps, synchronous DDM; medians of "
        f"{min(len(r) for r in runs.values())} run(s); packings identical on "
        f"{', '.join(str(t) for t in runs)} threads"
    )
    print()
    print("Table 1 layout (wall time, s):")
    print()
    print("| threads | total | contact detection | NLGS solve | subdomains (parallel) "
          "| interface (sequential) | set-up and error measure | other parts |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for t, m in med.items():
        print(f"| {t} | {m['total']:.1f} | {m['detect']:.1f} | {m['solve']:.1f} "
              f"| {m['subdomains']:.1f} | {m['interface']:.1f} | {m['solve_other']:.1f} "
              f"| {m['other']:.1f} |")
    print()
    print("Table 2 layout (speedup T1/Tp, efficiency Sp/p):")
    print()
    print("| threads | parallel part: speedup | efficiency | full: speedup | efficiency |")
    print("|---:|---:|---:|---:|---:|")
    base = med[min(med)]
    for t, m in med.items():
        sp = base["subdomains"] / m["subdomains"] if m["subdomains"] > 0 else float("nan")
        sf = base["total"] / m["total"]
        print(f"| {t} | {sp:.2f} | {100 * sp / t:.1f} % | {sf:.2f} | {100 * sf / t:.1f} % |")
    print()
    print(f"Targets: parallel part efficiency ≥ {100 * TARGET:.0f} % on 2 threads "
          f"(issue #7); the seed's OpenMP part reached {100 * SEED:.1f} % on 4 cores.")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "results/bench-ddm")
