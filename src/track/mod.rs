//! The track-impact scene of seed 004 §4 for `ballast-qdem`: a Type-3 sleeper on a
//! ballast bed (a `ballast-pack` packing), stones rigid or QDEM-deformable, vertex-sphere
//! contact ([`crate::dem`]), rail-seat loads from a CSV, sensors S1–S3 / B1–B3 sampled
//! at 10 kHz.

pub mod build;
pub mod loads;
pub mod run;
pub mod scene;

pub use build::{build, Sensor, SensorAt, Track};
pub use loads::RailSeatLoads;
pub use run::{is_track_scene, run};
pub use scene::TrackScene;
