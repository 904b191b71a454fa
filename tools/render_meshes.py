#!/usr/bin/env python3
"""Render the mesh gallery (the .vtu files `ballast-post meshes` wrote) to one PNG.

Reads every mesh with VTK's own XML reader, extracts its outer surface, and draws it
with matplotlib (no OpenGL, so it runs headless anywhere). Usage:

    render_meshes.py RESULTS_DIR OUT.png
"""
import json
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import vtk  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402


def surface_triangles(path):
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(str(path))
    reader.Update()
    surface = vtk.vtkDataSetSurfaceFilter()
    surface.SetInputData(reader.GetOutput())
    surface.Update()
    poly = surface.GetOutput()
    points = vtk_to_numpy(poly.GetPoints().GetData())
    cells = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
    return points[cells]


def shade(triangles, light=np.array([0.4, -0.6, 0.7])):
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-30
    intensity = 0.35 + 0.65 * np.clip(normals @ (light / np.linalg.norm(light)), 0, 1)
    return intensity


def main():
    results, out = Path(sys.argv[1]), Path(sys.argv[2])
    summary = json.loads((results / "summary.json").read_text())
    meshes = summary["figures"]["meshes"]
    cols = 3
    rows = math.ceil(len(meshes) / cols)
    fig = plt.figure(figsize=(4.2 * cols, 3.6 * rows), dpi=110)
    for k, mesh in enumerate(meshes):
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        tris = surface_triangles(results / mesh["vtu"])
        colour = np.array([0.55, 0.62, 0.72])
        faces = Poly3DCollection(tris, linewidths=0.15, edgecolors=(0.1, 0.1, 0.1, 0.35))
        faces.set_facecolor(np.outer(shade(tris), colour))
        ax.add_collection3d(faces)
        lo, hi = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_zlim(lo[2], hi[2])
        ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * (hi - lo).max()))
        ax.view_init(elev=22, azim=-58)
        ax.set_axis_off()
        ax.set_title(f"{mesh['name']}\n{mesh['nodes']} nodes, {mesh['tets']} tetra", fontsize=9)
    fig.tight_layout()
    fig.savefig(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
