//! One deformable solid on a tetra mesh — the verification scenes of seed 004 §3
//! (cantilever, creep–recovery, damped vibration) — as run by `ballast-qdem` and
//! `ballast-fem` from the same scene file: [`scene`] is the TOML schema, [`setup`]
//! turns it into solver inputs, [`qdem_run`] drives the explicit solver and writes its
//! outputs, [`analysis`] computes the headline figures.

pub mod analysis;
pub mod fem_run;
pub mod qdem_run;
pub mod scene;
pub mod setup;

pub use scene::SolidScene;
