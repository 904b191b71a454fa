//! `ballast-pack`: ballast beds by gravity deposition with the NSCD engine (seed 004 §4:
//! "the initial position of the ballast particles and sleeper was set by free fall";
//! seed 000 builds its 7-sleeper slice the same way).
//!
//! - [`scene`]: the bed scene file (stones, bed, sleepers, deposition, compaction);
//! - [`deposit`]: raining a column of stones, settling, strike-off, lowering the
//!   sleepers, crib ballast, floor vibration;
//! - [`report`]: compactness in control boxes by exact polyhedron clipping,
//!   coordination number, interpenetration;
//! - [`profile`]: the track-bed cross-section (crest, shoulders, slopes);
//! - [`packing`]: the packing file the solvers read;
//! - [`contacts`]: the contact impulses written with it, for a warm restart;
//! - [`recorder`]: what the run writes as it goes (CSV, frames, checkpoints);
//! - [`resume`]: checkpoints, and the bed restored from one (`--resume DIR`);
//! - [`tile`]: a long bed laid from one periodic bay's packing;
//! - [`run`]: `ballast-pack SCENE.toml` (files and summary).

pub mod contacts;
pub mod deposit;
pub mod packing;
pub mod profile;
pub mod recorder;
pub mod report;
pub mod resume;
pub mod run;
pub mod scene;
pub mod tile;

pub use packing::{Packing, Placement};
pub use scene::BedScene;
