//! DEM contact between bodies of seed 004 §4: a sphere at every surface vertex of a
//! body's tetra mesh (24 mm by default), contacts only between different bodies, a
//! linear normal spring and a tangential spring with a Coulomb slider, no dashpot
//! between deformable bodies (their viscosity lives in the material, eq. 7).
//!
//! - [`law`]: the spring–slider law of a material pair (Table 1's constants);
//! - [`neighbours`]: the cell-list broad phase, periodic along one axis if asked;
//! - [`contacts`]: the Verlet list with a skin, the per-pair springs carried across
//!   steps, deterministic parallel forces;
//! - [`rigid`]: 6-DOF rigid bodies with the same spheres (a stone far from the load);
//! - [`spheres`]: the per-step sphere buffers, and which spheres a step must update;
//! - [`system`]: QDEM bodies and rigid bodies stepped together.
//!
//! Only surface vertices get spheres: an interior vertex's sphere lies inside the body
//! (its surface neighbours' spheres cover it), so it would only cost time.

pub mod contacts;
pub mod law;
pub mod neighbours;
pub mod rigid;
pub mod spheres;
pub mod system;

pub use contacts::{
    ContactState, ContactTotals, Contacts, PairState, Plane, RestingPair, SphereSet,
};
pub use law::{ContactLaw, PairForce, SphereMaterial};
pub use neighbours::{close_pairs, Period};
pub use rigid::{RigidShape, RigidState};
pub use system::{
    BodyKind, MultiBody, MultiBodySolver, MultiState, SphereAt, SystemEnergies, SystemStability,
};
