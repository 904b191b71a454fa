"""CalculiX peer of `ballast-fem`: the same solid scene, mesh, fixes and loads, solved by
ccx (C3D4 linear tetra, a *STATIC step and a *FREQUENCY step).

Usage: ccx_peer.py SCENE.toml [--preset NAME] [--modes N] [--work DIR] [--keep]

Reads the scene TOML (presets deep-merged over the base as ballast does, arrays
replaced whole), the gmsh mesh through the gmsh Python API, and writes a CalculiX deck:
- every tetra as C3D4 (node order fixed to positive volume), one material (*ELASTIC,
  *DENSITY) and *SOLID SECTION;
- one node set per [[fix]] group, held in its directions by *BOUNDARY;
- each [[load]] as *CLOAD of total force / node count on every node of its group,
  exactly as ballast spreads it (the time function is ignored: statics); gravity as
  *DLOAD GRAV;
- *NODE PRINT of U for the probe nodes (no .frd output: ccx writes only the .dat);
- a *STATIC step, then a *FREQUENCY step for the lowest N modes (default [fem] modes,
  else 4). A free body ([[fix]] empty) skips the static step.

Runs ccx with OMP_NUM_THREADS, CCX_NPROC_EQUATION_SOLVER and CCX_NPROC_STIFFNESS set to
the core count, parses the .dat and prints one JSON line:
{tip_deflection_m, frequencies_hz, wall_time_s, nodes, tetra, solver, threads, ...}.
wall_time_s is ccx's own process time (reading the deck included); prepare_time_s is the
time this script spent reading the mesh and writing the deck.

[[fem.winkler]] beds are not translated (the script stops with a message).
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

# SI factor of the units the project's scenes use (the Rust side knows many more).
UNITS = {
    "N": 1.0,
    "kN": 1e3,
    "MN": 1e6,
    "Pa": 1.0,
    "kPa": 1e3,
    "MPa": 1e6,
    "GPa": 1e9,
    "kg/m^3": 1.0,
    "g/cm^3": 1e3,
    "t/m^3": 1e3,
    "m": 1.0,
    "cm": 1e-2,
    "mm": 1e-3,
    "m/s^2": 1.0,
    "s": 1.0,
    "ms": 1e-3,
    "N/m^3": 1.0,
    "kN/m^3": 1e3,
    "MN/m^3": 1e6,
    "N/mm^3": 1e9,
}


class SceneError(Exception):
    pass


def quantity(scene_path, key, text):
    """'200 N' -> 200.0 (SI); plain numbers pass through."""
    if isinstance(text, (int, float)):
        return float(text)
    match = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(\S*)\s*", str(text))
    if not match:
        raise SceneError(f"{scene_path}: key {key}: cannot read quantity {text!r}")
    value, unit = match.groups()
    if unit not in UNITS and unit != "":
        raise SceneError(
            f"{scene_path}: key {key}: unit {unit!r} unknown to ccx_peer.py "
            f"(knows: {', '.join(UNITS)})"
        )
    return float(value) * UNITS.get(unit, 1.0)


def merge(base, over):
    for key, value in over.items():
        if isinstance(base.get(key), dict) and isinstance(value, dict):
            merge(base[key], value)
        else:
            base[key] = value


def load_scene(path, preset):
    with open(path, "rb") as f:
        table = tomllib.load(f)
    presets = table.pop("preset", {})
    if preset is not None:
        if preset not in presets:
            raise SceneError(
                f"{path}: unknown preset {preset!r} (available: {', '.join(presets)})"
            )
        merge(table, presets[preset])
    return table


class Mesh:
    """Nodes, tetra and physical groups of a gmsh file (through the gmsh API)."""

    def __init__(self, path):
        import gmsh

        gmsh.initialize(readConfigFiles=False)
        try:
            gmsh.option.setNumber("General.Verbosity", 0)
            gmsh.open(str(path))
            tags, coords, _ = gmsh.model.mesh.getNodes()
            self.node_tags = np.asarray(tags, dtype=np.int64)
            self.coords = np.asarray(coords).reshape(-1, 3)
            types, _, _ = gmsh.model.mesh.getElements(3)
            if 4 not in types:
                raise SceneError(f"{path}: no 4-node tetrahedra")
            _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
            self.tets = np.asarray(tet_nodes, dtype=np.int64).reshape(-1, 4)
            self.groups = {}
            for dim, tag in gmsh.model.getPhysicalGroups():
                name = gmsh.model.getPhysicalName(dim, tag) or f"group_{tag}"
                nodes, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, tag)
                self.groups.setdefault(name, np.unique(np.asarray(nodes, dtype=np.int64)))
        finally:
            gmsh.finalize()
        # Keep only the nodes of the tetra (as ballast does) and orient them positively.
        used = np.unique(self.tets)
        index = np.full(self.node_tags.max() + 1, -1, dtype=np.int64)
        index[self.node_tags] = np.arange(len(self.node_tags))
        self.position = index
        self.used = used
        x = self.coords[index[self.tets]]
        volume = np.einsum(
            "ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0]
        )
        flip = volume < 0
        self.tets[flip] = self.tets[flip][:, [0, 2, 1, 3]]

    def group(self, scene_path, key, name):
        if name not in self.groups:
            raise SceneError(
                f"{scene_path}: key {key}.group: the mesh has no physical group {name!r} "
                f"(it has: {', '.join(self.groups)})"
            )
        return self.groups[name]

    def nearest(self, point):
        d = np.sum((self.coords[self.position[self.used]] - point) ** 2, axis=1)
        return np.array([self.used[int(np.argmin(d))]])


def write_lines(f, values, per_line=8):
    values = [str(v) for v in values]
    for i in range(0, len(values), per_line):
        f.write(", ".join(values[i : i + per_line]) + ",\n")


def write_deck(scene_path, scene, mesh, deck, modes):
    material = scene["material"]
    young = quantity(scene_path, "material.young_modulus", material["young_modulus"])
    density = quantity(scene_path, "material.density", material["density"])
    poisson = float(material["poisson"])
    if scene.get("fem", {}).get("winkler"):
        raise SceneError(
            f"{scene_path}: key fem.winkler: Winkler beds are not translated to CalculiX"
        )
    probes = {}
    for i, probe in enumerate(scene.get("probe", [])):
        if "group" in probe:
            probes[probe["name"]] = mesh.group(scene_path, f"probe[{i}]", probe["group"])
        else:
            point = [quantity(scene_path, f"probe[{i}].point", v) for v in probe["point"]]
            probes[probe["name"]] = mesh.nearest(np.array(point))
    fixes = scene.get("fix", [])
    static = bool(fixes)
    with open(deck, "w") as f:
        f.write("*HEADING\nballast-fem peer: " + Path(scene_path).name + "\n")
        f.write("*NODE, NSET=NALL\n")
        for tag in mesh.used:
            x = mesh.coords[mesh.position[tag]]
            f.write(f"{tag}, {x[0]:.17g}, {x[1]:.17g}, {x[2]:.17g}\n")
        f.write("*ELEMENT, TYPE=C3D4, ELSET=EALL\n")
        for i, t in enumerate(mesh.tets):
            f.write(f"{i + 1}, {t[0]}, {t[1]}, {t[2]}, {t[3]}\n")
        for i, fix in enumerate(fixes):
            f.write(f"*NSET, NSET=FIX{i}\n")
            write_lines(f, mesh.group(scene_path, f"fix[{i}]", fix["group"]))
        for name, nodes in probes.items():
            f.write(f"*NSET, NSET=P_{name.upper()}\n")
            write_lines(f, nodes)
        f.write("*MATERIAL, NAME=SOLID\n*ELASTIC\n")
        f.write(f"{young:.17g}, {poisson:.17g}\n*DENSITY\n{density:.17g}\n")
        f.write("*SOLID SECTION, ELSET=EALL, MATERIAL=SOLID\n")
        if fixes:
            f.write("*BOUNDARY\n")
            for i, fix in enumerate(fixes):
                for c, axis in enumerate("xyz"):
                    if axis in fix.get("directions", "xyz").lower():
                        f.write(f"FIX{i}, {c + 1}, {c + 1}\n")
        if static:
            f.write("*STEP\n*STATIC\n")
            loads = {}
            for i, load in enumerate(scene.get("load", [])):
                nodes = mesh.group(scene_path, f"load[{i}]", load["group"])
                force = [
                    quantity(scene_path, f"load[{i}].force[{c}]", v)
                    for c, v in enumerate(load["force"])
                ]
                for node in nodes:
                    total = loads.setdefault(int(node), [0.0, 0.0, 0.0])
                    for c in range(3):
                        total[c] += force[c] / len(nodes)
            if loads:
                f.write("*CLOAD\n")
                for node, force in sorted(loads.items()):
                    for c in range(3):
                        if force[c] != 0.0:
                            f.write(f"{node}, {c + 1}, {force[c]:.17g}\n")
            if "gravity" in scene:
                g = np.array(
                    [
                        quantity(scene_path, f"gravity[{c}]", v)
                        for c, v in enumerate(scene["gravity"])
                    ]
                )
                norm = float(np.linalg.norm(g))
                if norm > 0:
                    d = g / norm
                    f.write(f"*DLOAD\nEALL, GRAV, {norm:.17g}, {d[0]:.17g}, {d[1]:.17g}, {d[2]:.17g}\n")
            for name in probes:
                f.write(f"*NODE PRINT, NSET=P_{name.upper()}\nU\n")
            f.write("*END STEP\n")
        f.write(f"*STEP\n*FREQUENCY\n{modes}\n*END STEP\n")
    return probes, static


def parse_dat(path, probes):
    text = Path(path).read_text()
    lines = text.splitlines()
    displacements = {}
    frequencies = []
    i = 0
    while i < len(lines):
        line = lines[i]
        m = re.match(r"\s*displacements \(vx,vy,vz\) for set (\S+)", line)
        if m:
            values = {}
            i += 1
            while i < len(lines) and not lines[i].strip():
                i += 1
            while i < len(lines) and lines[i].strip():
                parts = lines[i].split()
                values[int(parts[0])] = [float(v) for v in parts[1:4]]
                i += 1
            # The print request stays active in the *FREQUENCY step, which prints the
            # mode shapes under the same header: keep the static step's block only.
            displacements.setdefault(m.group(1).upper(), values)
            continue
        if "E I G E N V A L U E   O U T P U T" in line:
            i += 1
            while i < len(lines):
                parts = lines[i].split()
                if len(parts) == 5 and parts[0].isdigit():
                    frequencies.append(float(parts[3]))
                elif frequencies and not lines[i].strip():
                    break
                i += 1
            continue
        i += 1
    probe_values = {}
    for name, nodes in probes.items():
        values = displacements.get(f"P_{name.upper()}")
        if values is None:
            continue
        u = np.mean([values[int(n)] for n in nodes], axis=0)
        probe_values[name] = u.tolist()
    return probe_values, frequencies


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--preset")
    parser.add_argument("--modes", type=int)
    parser.add_argument("--work", help="directory for the deck and ccx's files")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    args = parser.parse_args()
    ccx = shutil.which("ccx")
    if ccx is None:
        sys.exit("ccx_peer.py: ccx not found: run tools/peers/calculix/install.sh")
    try:
        start = time.perf_counter()
        scene_path = Path(args.scene)
        scene = load_scene(scene_path, args.preset)
        mesh_path = scene_path.parent / scene["mesh"]["file"]
        mesh = Mesh(mesh_path)
        modes = args.modes or scene.get("fem", {}).get("modes", 4)
        work = Path(args.work or tempfile.mkdtemp(prefix="ccx_peer_"))
        work.mkdir(parents=True, exist_ok=True)
        deck = work / "job.inp"
        probes, static = write_deck(scene_path, scene, mesh, deck, modes)
        prepare = time.perf_counter() - start
    except (SceneError, KeyError, OSError) as e:
        message = str(e) if isinstance(e, SceneError) else f"{args.scene}: {e!r}"
        sys.exit(f"ccx_peer.py: {message}")
    env = dict(os.environ)
    threads = str(args.threads)
    for name in ("OMP_NUM_THREADS", "CCX_NPROC_EQUATION_SOLVER", "CCX_NPROC_STIFFNESS",
                 "CCX_NPROC_RESULTS", "NUMBER_OF_CPUS"):
        env[name] = threads
    start = time.perf_counter()
    run = subprocess.run(
        [ccx, "-i", "job"], cwd=work, env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    (work / "ccx.log").write_text(run.stdout + run.stderr)
    if run.returncode != 0 or "*ERROR" in run.stdout:
        error = next((l for l in run.stdout.splitlines() if "*ERROR" in l), run.stderr.strip())
        sys.exit(f"ccx_peer.py: ccx failed ({run.returncode}) in {work}: {error}")
    log = run.stdout.lower()
    solver = "pardiso" if "pardiso" in log else "spooles" if "spooles" in log else "unknown"
    cpus = re.findall(r"using up to (\d+) cpu", log)
    probe_values, frequencies = parse_dat(work / "job.dat", probes)
    result = {
        "peer": "calculix",
        "scene": str(args.scene),
        "preset": args.preset,
        "nodes": int(len(mesh.used)),
        "tetra": int(len(mesh.tets)),
        "frequencies_hz": frequencies,
        "first_frequency_hz": frequencies[0] if frequencies else None,
        "probes": probe_values,
        "wall_time_s": wall,
        "prepare_time_s": prepare,
        "solver": solver,
        "threads": int(threads),
        "ccx_cpus_reported": sorted(set(int(c) for c in cpus)),
        "static": static,
        "work": str(work),
    }
    analysis = scene.get("analysis", {})
    if analysis.get("kind") == "static_deflection" and analysis.get("probe") in probe_values:
        result["tip_deflection_m"] = float(np.linalg.norm(probe_values[analysis["probe"]]))
    elif static and probe_values:
        name = next(iter(probe_values))
        result["tip_deflection_m"] = float(np.linalg.norm(probe_values[name]))
    m = re.search(r"total calculix time:\s*([0-9.eE+-]+)", log)
    if m:
        result["ccx_reported_time_s"] = float(m.group(1))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
