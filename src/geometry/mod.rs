//! Geometry helpers: convex polyhedra, mass properties and shape statistics of stones.
//!
//! - [`polyhedron`]: volume, area, centroid and inertia of a closed triangle surface
//!   (divergence theorem), convex hulls (parry3d);
//! - [`shape`]: PCA extents L ≥ I ≥ S, Wadell sphericity, sieve size, summaries;
//! - [`grain_library`]: the reader of the real grain library (`BIBLIGRAINS.DAT`);
//! - [`stone_family`]: the statistics of a generated stone family beside the library's
//!   and the EN 13450 grading band (`ballast-post stones DIR`);
//! - [`period`]: periodicity along one axis (wrap, minimum image), for the DEM and
//!   NSCD contact searches.

pub mod clip;
pub mod grain_library;
pub mod period;
pub mod polyhedron;
pub mod random;
pub mod shape;
pub mod stone_family;

pub use clip::{clipped_convex_volume, convex_volume_in_box, ControlBox};
pub use grain_library::{read_grain_library, Grain};
pub use period::Period;
pub use polyhedron::{convex_hull, convex_hull_volume, mass_properties, MassProperties};
pub use shape::{
    corner_vertices, pca_extents, sieve_size, wadell_sphericity, ShapeMeasures, Summary,
};
pub use stone_family::{measure_stone_mesh, stone_family_report, StoneMeasures, EN13450_31_5_50};
