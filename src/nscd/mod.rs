//! Non-smooth contact dynamics numerics (seed 000 §2.1): the frictional-contact problem,
//! the exact local 3-D Coulomb solver and the non-linear Gauss–Seidel (NSGS) sweep.
//!
//! Like Siconos's *numerics*, this module knows nothing of files, scenes or meshes:
//! [`problem::FrictionProblem`] (W form) is filled by the FC3D readers
//! ([`crate::fc3d`]); [`nlgs::solve`] takes it with [`nlgs::NlgsOptions`] and returns an
//! [`nlgs::NlgsReport`].
//!
//! # Two forms, one local solver
//! - **W form** (built): `u = W r + q`, W as block-sparse rows of 3 × 3 blocks. A sweep
//!   forms `q_a + Σ_b W_ab r_b` per contact. This is what the FC3D files give.
//! - **Body-velocity form** (the NSCD engine's, [`body_nlgs`]): `u_a = H_aᵀ v + w_a`,
//!   with `M v = H r + f` kept up to date: after contact a's local solve, the two bodies'
//!   velocities get `M⁻¹ H_a Δr_a` in place, so a sweep costs O(contacts) without ever
//!   assembling W. It needs only the diagonal blocks `W_aa = H_aᵀ M⁻¹ H_a` for the local
//!   solver, calls the same [`coulomb::LocalCoulomb::solve`], takes and returns the same
//!   options and report structs, and measures the error the same way on `u = Hᵀ v + w`.
//!   The domain decomposition ([`crate::ddm`]) runs its sweeps by subdomain.
//!
//! # Stopping
//! [`nlgs::Stopping::Tolerance`] stops when the Siconos error measure
//! ([`residual::siconos_error`]: `√(Σ_a ‖r_a − Π_K(r_a − ũ_a)‖²) / max(‖q‖, ‖r‖, ‖u‖)`)
//! is at most the tolerance, or at the sweep cap; [`nlgs::Stopping::Sweeps`] makes a
//! fixed number of sweeps (the seed's n_DDM).

pub mod body;
pub mod body_nlgs;
pub mod checkpoint;
pub mod coulomb;
pub mod motion;
pub mod nlgs;
pub mod packed;
pub mod problem;
pub mod residual;
pub mod run;
pub mod scene;
pub mod step;
pub mod tamping;

pub use body::{Body, BodyShape, Motion, Prescribed};
pub use coulomb::{ContactStatus, LocalCoulomb};
pub use nlgs::{ErrorCheck, NlgsOptions, NlgsReport, Stopping};
pub use problem::{Block3, DelassusBlocks, FrictionProblem};
pub use step::{DdmSetup, FrictionTable, MoreauJean, SolvedContact, StepParams, StepReport};
