#!/bin/sh
# Installs the Siconos peer: Debian's python3-siconos (Siconos 4.4 numerics) with h5py and
# scipy for the FCLIB .hdf5 files, all for Debian's /usr/bin/python3. Does nothing when
# they import already. Needs root (CI and the developers' machines run as root).
set -e
if /usr/bin/python3 -c 'import siconos.numerics, h5py, scipy' >/dev/null 2>&1; then
    exit 0
fi
apt-get update
DEBIAN_FRONTEND=noninteractive apt-get install -y python3-siconos python3-h5py python3-scipy
/usr/bin/python3 -c 'import siconos.numerics, h5py, scipy'
