//! `ballast`: ballasted railway track simulation from gmsh geometry to VTK results.
//!
//! Two methods share one pipeline (see `docs/DESIGN.md`):
//! - NSCD–DDM tamping of rigid polyhedral grains (Hoang et al., seed 000);
//! - QDEM impact of Kelvin–Voigt tetrahedral bodies (Nishiura et al., seed 004).
//!
//! The numerical cores take plain structs and slices; [`scene`] builds them from TOML,
//! [`mesh`] reads gmsh meshes and [`output`] writes VTK, CSV and JSON.
#![warn(missing_docs)]

pub mod cli;
pub mod contact;
pub mod ddm;
pub mod dem;
pub mod error;
pub mod fc3d;
pub mod fem;
pub mod geometry;
pub mod mesh;
pub mod nscd;
pub mod output;
pub mod pack;
pub mod post;
pub mod qdem;
pub mod scene;
pub mod signal;
pub mod simd;
pub mod solid;
pub mod track;

pub use error::{Error, Result};
