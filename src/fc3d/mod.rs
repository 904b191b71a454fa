//! Readers of the frictional-contact problems written by Siconos (FC3D): the `.dat` text
//! format in its dense and block-sparse storages ([`dat`]) and FCLIB HDF5 files in the
//! local and global layouts ([`fclib`]). Both fill the same [`FrictionProblem`] that
//! the NSGS solver takes; `../shared/fc3d/README.md` describes the formats.

pub mod dat;
pub mod fclib;

use std::path::Path;

use crate::nscd::FrictionProblem;

/// Which file layout a problem came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fc3dFormat {
    /// `.dat`, dense W.
    DatDense,
    /// `.dat`, block-sparse W (3 × 3 blocks).
    DatBlockSparse,
    /// FCLIB HDF5 `/fclib_local` (W, q, µ).
    FclibLocal,
    /// FCLIB HDF5 `/fclib_global` (M, H, f, w, µ), reduced to W = Hᵀ M⁻¹ H, q = Hᵀ M⁻¹ f + w.
    FclibGlobal,
}

impl Fc3dFormat {
    /// A short name for tables.
    pub fn label(self) -> &'static str {
        match self {
            Fc3dFormat::DatDense => "dat dense",
            Fc3dFormat::DatBlockSparse => "dat block-sparse",
            Fc3dFormat::FclibLocal => "FCLIB local",
            Fc3dFormat::FclibGlobal => "FCLIB global",
        }
    }
}

/// Reads an FC3D problem, choosing the reader from the file's first bytes (the HDF5
/// signature) rather than from its name (`*.hdf5.dat` files are text).
pub fn read(path: &Path) -> crate::Result<(FrictionProblem, Fc3dFormat)> {
    let bytes = std::fs::read(path).map_err(|e| crate::Error::io(path, e))?;
    if bytes.starts_with(b"\x89HDF\r\n\x1a\n") {
        drop(bytes);
        fclib::read(path)
    } else {
        let text = String::from_utf8(bytes)
            .map_err(|_| crate::Error::invalid(path, "neither HDF5 nor a UTF-8 .dat text"))?;
        dat::parse(&text).map_err(|what| crate::Error::invalid(path, what))
    }
}
