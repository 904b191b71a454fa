#!/usr/bin/python3
"""Solve FC3D problems with Siconos NSGS (Debian python3-siconos, default local solver).

Usage: /usr/bin/python3 fc3d_nsgs.py [--tol T ...] [--max-iter N] [--repeat K] FILE...

Prints one JSON object per (file, tolerance) on stdout, with the keys of
`ballast-nscd fc3d --json`: file, contacts, tolerance, max_iter, iterations, error,
solver_time_s (the fastest of K runs, each from r = 0; reading not timed), converged.

`.dat` files are read by Siconos itself (frictionContact_new_from_filename). This Siconos
build has no FCLIB reader, so `.hdf5` files are read with h5py: /fclib_local gives W, q,
mu; /fclib_global gives W = H^T M^-1 H and q = H^T M^-1 f + w (M diagonal); W is then
handed to Siconos in its block-sparse (SBM) storage, as the block-sparse .dat files are.
"""

import argparse
import json
import os
import sys
import time

import numpy as np
import scipy.sparse as sp
import siconos.numerics as sn


def sparse_group(g):
    """An FCLIB sparse matrix group as a scipy CSR matrix."""
    m, n, nz = int(g["m"][0]), int(g["n"][0]), int(g["nz"][0])
    p, i, x = g["p"][()], g["i"][()], g["x"][()]
    if nz == -2:
        return sp.csr_matrix((x[: p[m]], i[: p[m]], p[: m + 1]), shape=(m, n))
    if nz == -1:
        return sp.csc_matrix((x[: p[n]], i[: p[n]], p[: n + 1]), shape=(m, n)).tocsr()
    return sp.coo_matrix((x[:nz], (i[:nz], p[:nz])), shape=(m, n)).tocsr()


def read_hdf5(path):
    import h5py

    with h5py.File(path, "r") as f:
        if "fclib_local" in f:
            g = f["fclib_local"]
            w = sparse_group(g["W"])
            q = g["vectors/q"][()]
            mu = g["vectors/mu"][()]
        else:
            g = f["fclib_global"]
            m = sparse_group(g["M"])
            h = sparse_group(g["H"])
            if (m - sp.diags(m.diagonal())).count_nonzero():
                raise ValueError(f"{path}: non-diagonal M")
            minv = sp.diags(1.0 / m.diagonal())
            w = (h.T @ minv @ h).tocsr()
            q = h.T @ (minv @ g["vectors/f"][()]) + g["vectors/w"][()]
            mu = g["vectors/mu"][()]
    return sbm_problem(w, np.asarray(q, dtype=float), np.asarray(mu, dtype=float))


def sbm_problem(w, q, mu):
    """The problem with W in Siconos's block-sparse (SBM) storage, the storage its NSGS
    gets from the block-sparse .dat files: written as such a .dat (full precision) and
    read back by Siconos itself."""
    import tempfile

    nc = len(mu)
    coo = w.tocoo()
    blocks = {}
    for i, j, x in zip(coo.row, coo.col, coo.data):
        blocks.setdefault((i // 3, j // 3), np.zeros((3, 3)))[i % 3, j % 3] += x
    keys = sorted(blocks)
    row_pointer = np.zeros(nc + 1, dtype=int)
    for a, _ in keys:
        row_pointer[a + 1] += 1
    row_pointer = np.cumsum(row_pointer)
    cumulative = " ".join(str(3 * (k + 1)) for k in range(nc))
    lines = ["3", str(nc), "1", f"{3 * nc} {3 * nc}", str(len(keys)), f"{nc} {nc}"]
    lines += [cumulative, cumulative, f"{nc + 1} {len(keys)}"]
    lines.append(" ".join(map(str, row_pointer)))
    lines.append(" ".join(str(b) for _, b in keys))
    for k, key in enumerate(keys):
        lines.append(str(k))
        lines.append(" ".join(repr(float(x)) for x in blocks[key].flatten(order="F")))
    lines.append(" ".join(repr(float(x)) for x in q))
    lines.append(" ".join(repr(float(x)) for x in mu))
    with tempfile.NamedTemporaryFile("w", suffix=".dat", delete=False) as f:
        f.write("\n".join(lines) + "\n")
        name = f.name
    try:
        return sn.frictionContact_new_from_filename(name)
    finally:
        os.unlink(name)


def load(path):
    with open(path, "rb") as f:
        magic = f.read(8)
    if magic == b"\x89HDF\r\n\x1a\n":
        return read_hdf5(path)
    return sn.frictionContact_new_from_filename(path)


def solve(problem, tol, max_iter):
    nc = problem.numberOfContacts
    r = np.zeros(3 * nc)
    u = np.zeros(3 * nc)
    options = sn.SolverOptions(sn.SICONOS_FRICTION_3D_NSGS)
    options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iter
    options.dparam[sn.SICONOS_DPARAM_TOL] = tol
    start = time.perf_counter()
    info = sn.fc3d_driver(problem, r, u, options)
    elapsed = time.perf_counter() - start
    return (
        info,
        int(options.iparam[sn.SICONOS_IPARAM_ITER_DONE]),
        float(options.dparam[sn.SICONOS_DPARAM_RESIDU]),
        elapsed,
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--tol", type=float, action="append")
    parser.add_argument("--max-iter", type=int, default=10000)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    tolerances = args.tol or [1e-8]
    for path in args.files:
        problem = load(path)
        for tol in tolerances:
            runs = [solve(problem, tol, args.max_iter) for _ in range(max(1, args.repeat))]
            info, iterations, error, _ = runs[-1]
            record = {
                "file": os.path.basename(path),
                "contacts": problem.numberOfContacts,
                "tolerance": tol,
                "max_iter": args.max_iter,
                "iterations": iterations,
                "error": error,
                "solver_time_s": min(run[3] for run in runs),
                "converged": info == 0,
            }
            print(json.dumps(record), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
