"""ballast-fem against CalculiX (and QDEM, when its runs exist) on the cantilever of
seed 004 §3.1 (scenes/cantilever_static.toml): `make compare-fem`.

  compare_fem.py ballast LEVEL OUT.json     run `ballast-fem both` (static + modes) at LEVEL
  compare_fem.py table LEVEL... --dir DIR   print the markdown table

LEVEL is a preset of scenes/cantilever_static.toml (h005, h002, paper) or `base` (no
preset, h = 0.03 m). `ballast` runs `ballast-fem both` (the static solve and 4 modes in
one process, as CalculiX does them in one run) and records its wall time (process start
to exit: reading the mesh and writing the VTK included) and the solver phases from summary.json. `table` reads
DIR/LEVEL/ballast.json and DIR/LEVEL/calculix.json (ccx_peer.py's line), looks for QDEM
runs of the same mesh under results/paper/cantilever_static-*/ and
cantilever_vibration-*/ (`make paper`), else under results/ (`make qdem-quick`),
matched on the mesh file in their summary's inputs ("not run" otherwise: compare-fem
never runs QDEM), and adds the beam theories:

- Euler–Bernoulli: δ = PL³/3EI, f₁ = 1.875104² / (2π L²) √(EI/ρA) (seed 004 eqs. 12–13:
  92.32 µm, 27.01 Hz);
- Timoshenko: δ = PL³/3EI + PL/(κGA), G = E/2(1+ν), with Cowper's shear coefficient for
  a rectangle κ = 10(1+ν)/(12+11ν) (G. R. Cowper, J. Appl. Mech. 33 (1966) 335); f₁ of
  the clamped–free Timoshenko beam (shear and rotary inertia; S. P. Timoshenko, Phil.
  Mag. 41 (1921) 744) computed here to 1e-7 by a converged 1-D Timoshenko beam model
  (linear elements, one-point shear integration, consistent translational and rotary
  mass, Richardson extrapolation over 400/800 elements).
"""

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SCENE = "scenes/cantilever_static.toml"
BINARY = os.environ.get("BALLAST_FEM", "target/release/ballast-fem")

# scenes/cantilever_static.toml: concrete beam, 200 N at the free end.
E, NU, RHO = 45e9, 0.167, 2350.0
B, H, L, P = 0.25, 0.22, 2.4, 200.0


def run_ballast(level, out_json):
    out = Path(out_json).parent
    preset = [] if level == "base" else ["--preset", level]
    directory = out / "ballast"
    start = time.perf_counter()
    run = subprocess.run(
        [BINARY, "both", SCENE, *preset, "--out", str(directory)],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - start
    if run.returncode != 0:
        sys.exit(f"compare_fem.py: ballast-fem both failed: {run.stderr.strip()}")
    summary = json.loads((directory / "summary.json").read_text())
    figures = summary["figures"]
    result = {
        "level": level,
        "nodes": figures["nodes"],
        "tetra": figures["tetra"],
        "threads": summary["threads"],
        "wall_s": wall,
        "solver_s": figures["solver_wall_time_s"],
        "phases_s": summary["wall_time_s"],
        "tip_deflection_m": figures["tip_deflection_m"],
        "frequencies_hz": figures["frequencies_hz"],
    }
    Path(out_json).write_text(json.dumps(result) + "\n")
    print(json.dumps(result))


def euler_bernoulli():
    inertia = B * H**3 / 12
    deflection = P * L**3 / (3 * E * inertia)
    frequency = 1.875104**2 / (2 * math.pi * L**2) * math.sqrt(E * inertia / (RHO * B * H))
    return deflection, frequency


def cowper_kappa():
    return 10 * (1 + NU) / (12 + 11 * NU)


def timoshenko_deflection(kappa):
    shear = E / (2 * (1 + NU))
    return euler_bernoulli()[0] + P * L / (kappa * shear * B * H)


def timoshenko_frequency(kappa, elements):
    """First frequency of the clamped–free Timoshenko beam, 1-D FE."""
    shear = E / (2 * (1 + NU))
    area, inertia = B * H, B * H**3 / 12
    l = L / elements
    n = 2 * (elements + 1)
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    bending = E * inertia / l * np.array(
        [[0, 0, 0, 0], [0, 1, 0, -1], [0, 0, 0, 0], [0, -1, 0, 1]], dtype=float
    )
    b = np.array([-1 / l, -0.5, 1 / l, -0.5])
    shear_k = kappa * shear * area * l * np.outer(b, b)
    pair = l / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
    for e in range(elements):
        dofs = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3]
        K[np.ix_(dofs, dofs)] += bending + shear_k
        w = [2 * e, 2 * e + 2]
        t = [2 * e + 1, 2 * e + 3]
        M[np.ix_(w, w)] += RHO * area * pair
        M[np.ix_(t, t)] += RHO * inertia * pair
    K, M = K[2:, 2:], M[2:, 2:]  # clamp w and θ at x = 0
    chol = np.linalg.cholesky(M)
    inv = np.linalg.inv(chol)
    lam = np.linalg.eigvalsh(inv @ K @ inv.T)[0]
    return math.sqrt(lam) / (2 * math.pi)


def timoshenko():
    kappa = cowper_kappa()
    coarse = timoshenko_frequency(kappa, 400)
    fine = timoshenko_frequency(kappa, 800)
    return timoshenko_deflection(kappa), fine + (fine - coarse) / 3


def mesh_of_level(level):
    import tomllib

    with open(SCENE, "rb") as f:
        scene = tomllib.load(f)
    if level != "base":
        return scene["preset"][level].get("mesh", {}).get("file", scene["mesh"]["file"])
    return scene["mesh"]["file"]


def qdem_figure(scene, mesh, figure):
    """The figure of a QDEM run of `scene` on `mesh`: results/paper/<scene>-*/ (`make
    paper`) first, then results/<scene>-*/ (`make qdem-quick`); (None, None) if none."""
    candidates = sorted(Path("results/paper").glob(f"{scene}-*/summary.json"))
    candidates += sorted(Path("results").glob(f"{scene}-*/summary.json"))
    for path in candidates:
        try:
            summary = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if summary.get("inputs", {}).get("mesh", {}).get("file") == mesh:
            value = summary.get("figures", {}).get(figure)
            if value is not None:
                return value, str(path.parent)
    return None, None


def load(path):
    try:
        lines = [l for l in Path(path).read_text().splitlines() if l.startswith("{")]
        return json.loads(lines[-1]) if lines else None
    except OSError:
        return None


def fmt(value, digits):
    return "—" if value is None else f"{value:.{digits}f}"


def rel(a, b):
    if a is None or b is None:
        return "—"
    return f"{(a - b) / b:+.2e}"


def table(levels, directory):
    eb_deflection, eb_frequency = euler_bernoulli()
    t_deflection, t_frequency = timoshenko()
    rows = []
    notes = []
    for level in levels:
        ours = load(Path(directory) / level / "ballast.json")
        ccx = load(Path(directory) / level / "calculix.json")
        mesh = mesh_of_level(level)
        q_deflection, q_static = qdem_figure("cantilever_static", mesh, "tip_deflection_m")
        q_frequency, q_vib = qdem_figure("cantilever_vibration", mesh, "first_frequency_hz")
        if q_static:
            notes.append(f"{level}: QDEM deflection from {q_static}")
        if q_vib:
            notes.append(f"{level}: QDEM frequency from {q_vib}")
        o_defl = ours and ours.get("tip_deflection_m")
        c_defl = ccx and ccx.get("tip_deflection_m")
        o_freq = ours and ours.get("frequencies_hz", [None])[0]
        c_freq = ccx and ccx.get("first_frequency_hz")
        o_wall = ours and ours["wall_s"]
        o_solver = ours and ours["solver_s"]
        c_wall = ccx and ccx.get("wall_time_s")
        rows.append(
            "| {level} ({mesh}) | {nodes} | {tetra} | {qd} | {od} | {cd} | {dd} | {qf} | {of} | "
            "{cf} | {df} | {ow} ({os}) | {cw} | {ratio} |".format(
                level=level,
                mesh=Path(mesh).stem.replace("cantilever_", ""),
                nodes=(ours or ccx or {}).get("nodes", "—"),
                tetra=(ours or ccx or {}).get("tetra", "—"),
                qd="not run" if q_deflection is None else fmt(q_deflection * 1e6, 3),
                od=fmt(o_defl and o_defl * 1e6, 4),
                cd=fmt(c_defl and c_defl * 1e6, 4),
                dd=rel(o_defl, c_defl),
                qf="not run" if q_frequency is None else fmt(q_frequency, 3),
                of=fmt(o_freq, 4),
                cf=fmt(c_freq, 4),
                df=rel(o_freq, c_freq),
                ow=fmt(o_wall, 2),
                os=fmt(o_solver, 2),
                cw=fmt(c_wall, 2),
                ratio="—" if not (o_wall and c_wall) else f"{c_wall / o_wall:.2f}",
            )
        )
        if ccx:
            notes.append(
                f"{level}: CalculiX {ccx.get('solver')} with {ccx.get('threads')} threads; "
                f"ballast-fem {ours.get('threads') if ours else '—'} threads"
            )
    header = (
        "| resolution | nodes | tetra | QDEM δ (µm) | ballast-fem δ (µm) | CalculiX δ (µm) | "
        "δ ours/ccx − 1 | QDEM f₁ (Hz) | ballast-fem f₁ (Hz) | CalculiX f₁ (Hz) | "
        "f₁ ours/ccx − 1 | ballast-fem static + modes wall s (solver s) | CalculiX static + "
        "4 modes wall s | CalculiX / ballast-fem |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    )
    print("## Cantilever of seed 004 §3.1: ballast-fem, CalculiX, QDEM and beam theory\n")
    print(header)
    for row in rows:
        print(row)
    print(
        f"| Euler–Bernoulli | | | | {eb_deflection * 1e6:.2f} | | | | {eb_frequency:.2f} | | | | | |"
    )
    print(
        f"| Timoshenko, κ = {cowper_kappa():.4f} | | | | {t_deflection * 1e6:.2f} | | | | "
        f"{t_frequency:.3f} | | | | | |"
    )
    print(
        "\nδ: |u| at the tip-centre probe under 200 N spread equally over the tip face's "
        "nodes (same nodes and per-node force in both codes). f₁: lowest mode, clamped end. "
        "Wall times: whole processes (ballast-fem: `ballast-fem both`, the static solve and "
        "4 modes in one process sharing one Cholesky factor of K, VTK output included; in "
        "brackets the solver phases only — assembly, ordering, factorisation, solves, "
        "eigensolver; CalculiX: one ccx run with a *STATIC and a "
        "*FREQUENCY step of 4 modes; it writes the mode shapes to its .frd by default). Seed 004 quotes 92.32 µm and 27.01 Hz "
        "for Euler–Bernoulli. CalculiX integrates the C3D4 mass matrix at one point (ρV/16 "
        "in every entry), ballast-fem uses the exact consistent mass: its frequencies are "
        "slightly lower on the same mesh; the difference shrinks as h² (checked: an independent "
        "scipy model with the one-point mass reproduces ccx's 28.74368 Hz on the h005 mesh "
        "to all printed digits, and the exact mass gives ballast-fem's 28.74123 Hz). QDEM "
        "uses lumped vertex masses (ρV/4), which lowers its frequency further.\n"
    )
    for note in notes:
        print(f"- {note}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("ballast")
    p.add_argument("level")
    p.add_argument("out")
    t = sub.add_parser("table")
    t.add_argument("levels", nargs="+")
    t.add_argument("--dir", default="results/compare_fem")
    args = parser.parse_args()
    if args.command == "ballast":
        run_ballast(args.level, args.out)
    else:
        table(args.levels, args.dir)


if __name__ == "__main__":
    main()
