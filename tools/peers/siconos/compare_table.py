#!/usr/bin/python3
"""Side-by-side table of `ballast-nscd fc3d --json` and `fc3d_nsgs.py` records.

Usage: compare_table.py OURS.jsonl SICONOS.jsonl

Each side may hold several runs of a (file, tolerance): iterations and error must agree
between them (both solvers are deterministic) and the fastest time is kept. Prints a
Markdown table, one row per file, then the acceptance counts.
"""

import json
import sys


def load(path):
    runs = {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line.startswith("{"):
                continue
            record = json.loads(line)
            key = (record["file"], float(record["tolerance"]))
            best = runs.get(key)
            if best is not None:
                if (best["iterations"], best["error"]) != (record["iterations"], record["error"]):
                    sys.exit(f"{path}: {key} gave two different answers")
                if record["solver_time_s"] >= best["solver_time_s"]:
                    continue
            runs[key] = record
    return runs


def cell(record):
    if record is None:
        return "missing"
    capped = "*" if record["iterations"] >= record["max_iter"] else ""
    error = record["error"]
    error = "nan" if error is None else f"{error:.1e}"
    return f"{record['iterations']}{capped} / {error} / {record['solver_time_s']:.1e}"


def main():
    ours, siconos = load(sys.argv[1]), load(sys.argv[2])
    tolerances = sorted({tol for _, tol in ours} | {tol for _, tol in siconos}, reverse=True)
    files = sorted({name for name, _ in ours} | {name for name, _ in siconos}, key=str.lower)
    header = ["file", "contacts"]
    for tol in tolerances:
        header += [f"ours {tol:.0e}", f"Siconos {tol:.0e}"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    rows = error_ok = faster = big_rows = big_faster = 0
    for name in files:
        contacts = next(r["contacts"] for (n, _), r in {**siconos, **ours}.items() if n == name)
        line = [name, str(contacts)]
        for tol in tolerances:
            a, b = ours.get((name, tol)), siconos.get((name, tol))
            line += [cell(a), cell(b)]
            rows += 1
            if a is None or b is None:
                continue
            # No worse: ours meets the tolerance, or reaches Siconos's own final error (to
            # 1e-6 relative: two NSGS runs that differ only in rounding tie).
            if a["error"] is not None and a["error"] <= max(tol, (b["error"] or 0.0) * (1 + 1e-6)):
                error_ok += 1
            quicker = a["solver_time_s"] < b["solver_time_s"]
            faster += quicker
            if contacts >= 50:
                big_rows += 1
                big_faster += quicker
        print("| " + " | ".join(line) + " |")
    print()
    print("Cells: sweeps / Siconos error measure / solver seconds (fastest of the runs); "
          "* = the 10 000-sweep cap was hit.")
    print(f"Error no worse (ours <= max(tol, Siconos's x (1 + 1e-6))): {error_ok} of {rows} runs.")
    print(f"Ours faster: {faster} of {rows} runs; on problems with >= 50 contacts: "
          f"{big_faster} of {big_rows}.")
    return 0 if error_ok == rows else 1


if __name__ == "__main__":
    sys.exit(main())
