//! QDEM: the quadruple discrete element method of Nishiura et al. (seed 004 §2–3) for
//! Kelvin–Voigt bodies meshed with linear tetrahedra — numerics only (plain structs and
//! slices; scenes, meshes files and output live elsewhere).
//!
//! Map of the paper onto the code:
//! - eq. 1 (F = dx dX⁻¹ from the four vertices): `element`, `element_stress`,
//!   F = D_s D_m⁻¹ with D_m⁻¹ precomputed per tetra in [`QdemModel`];
//! - eq. 2–4 (T_E = λ tr ε I + 2µ ε, ε = (B − I)/2, B = F Fᵀ): same function;
//! - eq. 5–7 (L = dv dx⁻¹, D = sym L, T_D = λ_D tr D I + 2µ_D D): same function, with
//!   λ_D, µ_D from the shear and bulk viscosities ([`QdemMaterial`]);
//! - eq. 8 (T = T_E + T_D): [`QdemModel::stresses`] and the force kernel;
//! - eq. 9–10 (forces on the twelve sub-surfaces of Figure 1a): [`subsurface_forces`]
//!   literally, and the hot loop (`kernel`, four tetra per SIMD batch) in the equivalent
//!   closed form f_k = −(1/6) T (adj D_s)_k = −V T ∇N_k in the current configuration
//!   (tests: equal to round-off; batched = scalar bit for bit);
//! - eq. 11 (sum over the tetra sharing a particle): the coloured block assembly
//!   (`colouring`: Morton-ordered blocks of 256 tetra, blocks sharing a node get
//!   different colours; bitwise identical results for any thread count);
//! - §2.4 quarter masses and explicit Verlet: [`QdemModel::node_masses`], [`QdemSolver`];
//! - stable time step: [`stability`] (Lanczos ω_max of the lumped-mass mesh, viscous
//!   correction (√(1+ξ²) − ξ)); a run's dt is checked against it, and a blow-up stops
//!   with an error that names it;
//! - eq. 14 (Kelvin–Voigt creep): checked in `tests/qdem_core.rs`.
//!
//! Typical use:
//! ```
//! use ballast::qdem::*;
//! use nalgebra::Vector3;
//! let (nodes, tets) = structured_box(Vector3::new(1.0, 0.2, 0.2), [5, 1, 1]);
//! let model = QdemModel::new(&nodes, &tets, &QdemMaterial::elastic(2350.0, 45e9, 0.167))?;
//! let mut boundary = Boundary::default();
//! let fixed: Vec<u32> = (0..nodes.len() as u32).filter(|&n| nodes[n as usize].x == 0.0).collect();
//! boundary.constraints.fix(&fixed, Directions::ALL);
//! let dt = stability(&model).recommended();
//! let mut solver = QdemSolver::new(&model, &boundary, dt, QdemOptions::default())?;
//! let mut state = State::at_rest(&model);
//! solver.advance(&mut state, 10)?;
//! # Ok::<(), ballast::Error>(())
//! ```

mod boundary;
mod colouring;
mod element;
mod energy;
mod integrate;
mod kernel;
mod material;
mod model;
mod stability;
mod structured;

pub use boundary::{Boundary, Constraints, Directions, GroupSpring, NodalLoad, TimeFunction};
pub use element::{linear_tetra_forces, subsurface_forces, von_mises};
pub use energy::Energies;
pub use integrate::{Damping, ForceHook, QdemOptions, QdemSolver, State};
pub use material::QdemMaterial;
pub use model::{ElementTotals, QdemModel};
pub use stability::{stability, stable_time_step, StableTimeStep, RECOMMENDED_FRACTION};
pub use structured::structured_box;
