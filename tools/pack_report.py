"""Chart and table of a ballast-pack run, from what it wrote (summary.json,
deposit.csv).

  pack_report.py chart DIR OUT.png   deposition history and compactness per control box
  pack_report.py table DIR...        one markdown row per run (grains, d50, compactness,
                                     interpenetration, coordination, wall time)
  pack_report.py settle DIR [FROM_S] per phase of deposit.csv (from simulated time FROM_S
                                     on): steps, steps on the sweep cap, steps whose
                                     energy rise (ΔKE − work of gravity) is positive and
                                     their sum, and the last step's kinetic energy,
                                     fastest body point and deepest overlap, and its
                                     strongest contact (over the bed's weight when the
                                     summary gives it; above 1, a self-stress): what a
                                     phase that did not settle was doing (docs/pack.md,
                                     "Final settle: the capped solve feeds the bed")
"""

import csv
import json
import os
import sys

# Solid fraction of railway ballast in track: porosity 0.35-0.45 (Indraratna, Salim &
# Rujikiatkamjorn, Advanced Rail Geotechnology - Ballasted Track, 2011, ch. 2).
PUBLISHED_BAND = (0.55, 0.65)


def load(directory):
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    rows = []
    with open(os.path.join(directory, "deposit.csv")) as f:
        for row in csv.DictReader(f):
            rows.append({k: float(v) for k, v in row.items()})
    return summary, rows


def chart(directory, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary, rows = load(directory)
    fig = summary["figures"]
    phases = [p["name"] for p in fig["phases"]]
    t = [r["time_s"] for r in rows]
    ke = [max(r["kinetic_energy_J"], 1e-12) for r in rows]
    stones = [r["stones"] for r in rows]
    pen = [1e3 * r["max_interpenetration_m"] for r in rows]

    figure, (history, boxes) = plt.subplots(1, 2, figsize=(12, 4.5))
    history.semilogy(t, ke, color="tab:blue", lw=1)
    history.set_xlabel("simulated time (s)")
    history.set_ylabel("kinetic energy (J)", color="tab:blue")
    twin = history.twinx()
    twin.plot(t, stones, color="tab:green", lw=1.2, label="stones")
    twin.plot(t, [p * 100 for p in pen], color="tab:red", lw=0.8, label="max overlap (10 µm)")
    twin.set_ylabel("stones / max overlap (10 µm)")
    twin.legend(loc="center right", fontsize=8)
    # Shade the phases (their index is the csv's phase column).
    start = 0
    colours = ["#f0f0f0", "#ffffff"]
    for k in range(len(rows)):
        last = k + 1 == len(rows) or rows[k + 1]["phase"] != rows[k]["phase"]
        if last:
            history.axvspan(t[start], t[k], color=colours[int(rows[k]["phase"]) % 2], zorder=0)
            start = k + 1
    periodic = summary["inputs"]["bed"].get("sides") == "periodic"
    history.set_title(
        f"deposition: {fig['grains']} stones, d50 {1e3 * fig['d50_m']:.1f} mm, "
        f"{fig['steps']} steps" + (", periodic along the track" if periodic else ""),
        fontsize=10,
    )

    names = [c["box"] for c in fig["compactness"]]
    values = [c["value"] for c in fig["compactness"]]
    boxes.axhspan(*PUBLISHED_BAND, color="tab:orange", alpha=0.2,
                  label="ballast in track 0.55–0.65 (Indraratna et al. 2011)")
    bars = boxes.bar(names, values, color="tab:gray")
    for bar, value in zip(bars, values):
        boxes.text(bar.get_x() + bar.get_width() / 2, value + 0.005, f"{value:.3f}",
                   ha="center", fontsize=8)
    boxes.set_ylim(0.4, 0.7)
    boxes.set_ylabel("solid fraction (exact clipping)")
    boxes.set_title(
        f"compactness per control box; mean overlap "
        f"{100 * fig['mean_interpenetration_over_d50']:.3f} % d50", fontsize=10
    )
    boxes.legend(loc="lower right", fontsize=8)
    boxes.tick_params(axis="x", labelsize=8)
    figure.tight_layout()
    figure.savefig(out, dpi=110)
    print(f"pack_report: wrote {out} ({', '.join(phases)})")


def table(directories):
    print("| run | grains | d50 (mm) | compactness per box | mean / max overlap (% d50) "
          "| coordination | steps | stepping (s) | grains·steps/s |")
    print("|---|---:|---:|---|---:|---:|---:|---:|---:|")
    for d in directories:
        summary, _ = load(d)
        f = summary["figures"]
        boxes = ", ".join(f"{c['box']} {c['value']:.3f}" for c in f["compactness"])
        print(
            f"| {os.path.basename(os.path.normpath(d))} | {f['grains']} | "
            f"{1e3 * f['d50_m']:.1f} | {boxes} | "
            f"{100 * f['mean_interpenetration_over_d50']:.4f} / "
            f"{100 * f['max_interpenetration_over_d50']:.3f} | "
            f"{f['coordination_number']:.2f} | {f['steps']} | {f['stepping_s']:.0f} | "
            f"{f['grains_steps_per_s']:.3g} |"
        )


def settle(directory, start=0.0):
    summary, rows = load(directory)
    # The scene's caps: a phase whose most sweeps is one of them stopped on it. They are
    # the last run's (a run resumed with another `finish_sweeps` shows the phases before
    # the resume as off the cap).
    deposit = summary["inputs"]["deposit"]
    caps = {deposit.get("max_sweeps", 100), deposit.get("finish_sweeps", 500)}
    rows = [r for r in rows if r["time_s"] > start]
    # deposit.csv numbers its phases in the order they first step (a stage's part after
    # a strike-off is a phase of its own there), so they are named by time span.
    # The bed's weight (stones and sleepers, true): summaries since 2026-12-07.
    weight = summary["figures"].get("bed_weight_N")
    print(f"{directory}: deposit.csv from t = {start} s"
          + (f"; bed weight {1e-3 * weight:.2f} kN" if weight else ""))
    print("| csv phase | t (s) | steps | on the sweep cap | energy rise > 0 (steps, sum mJ) "
          "| last KE (mJ) | last fastest point (mm/s) | last deepest overlap (µm) "
          "| strongest contact (kN" + (", / bed weight)" if weight else ")") + " |")
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for index in sorted({int(r["phase"]) for r in rows}):
        mine = [r for r in rows if int(r["phase"]) == index]
        most = max(r["nlgs_sweeps"] for r in mine)
        on_cap = sum(r["nlgs_sweeps"] == most for r in mine) if most in caps else 0
        last = mine[-1]
        # deposit.csv of runs before 2026-12-06 has neither column.
        if "energy_rise_J" in last:
            rises = [r["energy_rise_J"] for r in mine if r["energy_rise_J"] > 0]
            rise = f"{len(rises)}, {1e3 * sum(rises):.1f}"
            fastest = f"{1e3 * last['fastest_point_m_s']:.1f}"
        else:
            rise, fastest = "—", "—"
        # Since 2026-12-04.
        if "max_contact_force_N" in last:
            force = max(r["max_contact_force_N"] for r in mine)
            strongest = f"{1e-3 * force:.3g}" + (f" / {force / weight:.2f}" if weight else "")
        else:
            strongest = "—"
        print(f"| {index} | {mine[0]['time_s']:.3f}–{last['time_s']:.3f} | {len(mine)} | "
              f"{on_cap} (most {most:.0f}) | {rise} | {1e3 * last['kinetic_energy_J']:.3g} | "
              f"{fastest} | {1e6 * last['max_interpenetration_m']:.1f} | {strongest} |")


def main(argv):
    if len(argv) == 4 and argv[1] == "chart":
        chart(argv[2], argv[3])
    elif len(argv) in (3, 4) and argv[1] == "settle":
        settle(argv[2], float(argv[3]) if len(argv) == 4 else 0.0)
    elif len(argv) >= 3 and argv[1] == "table":
        table(argv[2:])
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main(sys.argv)
