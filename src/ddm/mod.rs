//! Primal domain decomposition of the NLGS (seed 000 §2.2 and §4), run in parallel.
//!
//! - [`partition`]: grains to subdomains by the box that holds their mass centre (one
//!   slab per sleeper, or a regular grid), contacts numbered subdomain by subdomain,
//!   then the interface Γ;
//! - [`driver`]: the synchronous driver (subdomains in parallel, then Γ sequentially:
//!   Algorithm 1) and the asynchronous one (Γ as one more parallel block: §4.1's block
//!   Jacobi splitting), both on the body-velocity NLGS of [`crate::nscd::body_nlgs`].
//!
//! Like [`crate::nscd`], this module knows nothing of files: the NSCD step
//! ([`crate::nscd::MoreauJean`]) partitions its bodies every step and calls
//! [`driver::solve`].

pub mod driver;
pub mod partition;

pub use driver::{solve, DdmOptions, DdmReport, Driver};
pub use partition::{decompose, Decomposition, Partitioning};
