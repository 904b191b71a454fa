#!/bin/sh
# Installs the CalculiX peer: Debian's calculix-ccx (ccx 2.20, SPOOLES direct solver and
# ARPACK for eigenvalues). Does nothing when `ccx` is on the PATH already. Needs root (CI
# and the developers' machines run as root). The driver, ccx_peer.py, runs with the
# project's venv (gmsh for the mesh, numpy).
set -e
if command -v ccx >/dev/null 2>&1; then
    exit 0
fi
apt-get update
DEBIAN_FRONTEND=noninteractive apt-get install -y calculix-ccx
command -v ccx >/dev/null
