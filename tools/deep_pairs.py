"""The most interpenetrated body pairs of a ballast-pack or ballast-nscd frame.

  deep_pairs.py FRAME.vtu [--period L] [--top N]

Reads a grains frame (triangles with a cell field `id` per body: `frames/bed_*.vtu`,
`frames/grains_*.vtu`) with VTK and, for every pair of bodies whose bounding spheres
overlap, computes the exact penetration depth of the two convex hulls: the smallest
overlap of their projections over every candidate axis of the separating-axis test
(each face normal of both bodies and every cross product of an edge of one with an edge
of the other; the minimum over this superset of the Minkowski difference's face normals
is the depth). Prints the N deepest pairs with the depth along face normals alone and
along edge axes alone, and the deepest vertex of one body inside the other, so that an
edge-through-edge overlap (deep, with no vertex deep inside) shows as such.

--period L: periodic along x with length L (a `sides = "periodic"` bed); pairs meet
through the minimum image.

This is how the impact bed's 9 mm pair of 2026-12-02 was found (docs/nscd.md, "Edges
over a corner"); it is a diagnostic, O(pairs × edges²) in numpy: about 15 s for 4 000
stones.
"""

import argparse

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def bodies_of(path):
    """Each body's hull vertices, centre, bounding radius, outward face planes and edge
    directions, from the frame's surface triangles."""
    reader = vtk.vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    points = vtk_to_numpy(grid.GetPoints().GetData())
    triangles = vtk_to_numpy(grid.GetCells().GetConnectivityArray()).reshape(-1, 3)
    ids = vtk_to_numpy(grid.GetCellData().GetArray("id"))
    bodies = {}
    for body in np.unique(ids):
        tri = triangles[ids == body]
        vertices = points[np.unique(tri.ravel())]
        centre = vertices.mean(0)
        a, b, c = points[tri[:, 0]], points[tri[:, 1]], points[tri[:, 2]]
        normals = np.cross(b - a, c - a)
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        offsets = (normals * a).sum(1)
        # Outward: the centre is below every face plane.
        sign = np.where((normals * centre).sum(1) > offsets, -1.0, 1.0)
        normals *= sign[:, None]
        offsets *= sign
        edges = set()
        for t in tri:
            for u, v in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                edges.add((min(u, v), max(u, v)))
        directions = np.array([points[v] - points[u] for u, v in sorted(edges)])
        directions /= np.linalg.norm(directions, axis=1)[:, None]
        radius = np.linalg.norm(vertices - centre, axis=1).max()
        bodies[int(body)] = (vertices, centre, radius, normals, offsets, directions)
    return bodies


def overlap(first, second, axes):
    """Overlap of the two point sets' projections on each axis (negative: apart)."""
    a, b = first @ axes.T, second @ axes.T
    return np.minimum(a.max(0) - b.min(0), b.max(0) - a.min(0))


def deepest_vertex(points, normals, offsets):
    """How deep the deepest of `points` is inside the hull of the planes (≤ 0: none)."""
    return -(points @ normals.T - offsets).max(1).min()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("frame")
    parser.add_argument("--period", type=float, default=None)
    parser.add_argument("--top", type=int, default=8)
    args = parser.parse_args()
    bodies = bodies_of(args.frame)
    keys = sorted(bodies)
    centres = np.array([bodies[k][1] for k in keys])
    radii = np.array([bodies[k][2] for k in keys])
    found = []
    for i, a in enumerate(keys):
        d = centres - centres[i]
        if args.period:
            d[:, 0] -= args.period * np.round(d[:, 0] / args.period)
        close = np.linalg.norm(d, axis=1) < radii + radii[i]
        near = np.where(close & (np.arange(len(keys)) > i))[0]
        va, _, _, na, oa, ea = bodies[a]
        for j in near:
            b = keys[j]
            shift = (centres[j] - centres[i]) - d[j]  # b's image next to a is b − shift
            vb, _, _, nb, ob, eb = bodies[b]
            vb = vb - shift
            faces = overlap(va, vb, np.vstack([na, nb])).min()
            if faces <= 0.0:
                continue
            axes = np.cross(ea[:, None, :], eb[None, :, :]).reshape(-1, 3)
            length = np.linalg.norm(axes, axis=1)
            axes = axes[length > 1e-6] / length[length > 1e-6][:, None]
            edges = overlap(va, vb, axes).min() if len(axes) else np.inf
            depth = min(faces, edges)
            if depth <= 0.0:
                continue
            # b's image: its planes n·x ≤ o move to n·x ≤ o − n·shift.
            vertex = max(deepest_vertex(va, nb, ob - nb @ shift), deepest_vertex(vb, na, oa))
            found.append((depth, faces, edges, vertex, a, b, centres[i]))
    found.sort(key=lambda f: -f[0])
    print(f"{len(bodies)} bodies, {len(found)} interpenetrating pairs")
    for depth, faces, edges, vertex, a, b, at in found[: args.top]:
        print(
            f"{1e3 * depth:8.3f} mm  bodies {a}-{b}  (faces {1e3 * faces:.3f}, edges "
            f"{1e3 * edges:.3f}, deepest vertex {1e3 * max(vertex, 0.0):.3f} mm) at "
            f"[{at[0]:.3f}, {at[1]:.3f}, {at[2]:.3f}] m"
        )


if __name__ == "__main__":
    main()
