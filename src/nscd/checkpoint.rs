//! Checkpoints of a `ballast-nscd` run, for `--resume DIR` after a run was killed.
//!
//! A checkpoint holds everything the next step depends on: every body's state, the
//! contacts' impulses that warm-start the next NLGS, the step counter, how many VTK
//! frames were written, and the run's running figures (`extra`: the residual
//! statistics, the analysis samples, the tamping monitor with its squeeze actuators).
//! The scene, the bodies' shapes and the prescribed motions come from the scene file
//! again; the checkpoint keeps the merged scene text and refuses to resume another.
//!
//! The file is written and read by [`crate::output::checkpoint`] (`checkpoint.bin`,
//! bincode, atomic rename, tag and scene checked). Resuming truncates
//! the CSV series and the `.pvd` collections back to the checkpoint's time, so a
//! resumed run's files are the uninterrupted run's files.

use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::{de::DeserializeOwned, Deserialize, Serialize};

use super::body::Body;
use crate::contact::{ContactKey, ImpulseMemory};
use crate::{Error, Result};

/// The format tag.
/// 2: the tamping monitor's largest tine deflection (sprung tines).
pub const CHECKPOINT_FORMAT: &str = "ballast-nscd checkpoint 2";

/// Keys of the merged scene a resumed run may change: how often it checkpoints, not
/// what it computes ([`crate::output::read_checkpoint_allowing`]).
pub const RUN_CONTROL_KEYS: [(&str, &str); 2] = [
    ("output", "checkpoint_every"),
    ("output", "checkpoint_wall_every"),
];

pub use crate::output::CHECKPOINT_FILE;

/// One body's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodyState {
    /// Mass centre (m).
    pub position: [f64; 3],
    /// Principal frame `[w, x, y, z]`.
    pub orientation: [f64; 4],
    /// Velocity (m/s).
    pub velocity: [f64; 3],
    /// Angular velocity in the principal frame (rad/s).
    pub angular_velocity: [f64; 3],
}

impl BodyState {
    /// The state of `body`.
    pub fn of(body: &Body) -> Self {
        let v = |v: &Vector3<f64>| [v.x, v.y, v.z];
        let q = body.orientation.quaternion();
        BodyState {
            position: v(&body.position),
            orientation: [q.w, q.i, q.j, q.k],
            velocity: v(&body.velocity),
            angular_velocity: v(&body.angular_velocity),
        }
    }

    /// Puts this state into `body` (bit for bit).
    pub fn apply(&self, body: &mut Body) {
        let [w, x, y, z] = self.orientation;
        body.position = Vector3::from(self.position);
        body.orientation = UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z));
        body.velocity = Vector3::from(self.velocity);
        body.angular_velocity = Vector3::from(self.angular_velocity);
    }
}

/// A run's state after a step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint<T> {
    /// [`CHECKPOINT_FORMAT`].
    pub format: String,
    /// The merged scene (after preset and overrides), as TOML text.
    pub scene: String,
    /// Steps done.
    pub step: u64,
    /// Time reached (s).
    pub time: f64,
    /// VTK frames written (the initial one included).
    pub frames: usize,
    /// Every body, in scene order.
    pub bodies: Vec<BodyState>,
    /// The warm-start impulses, sorted by key.
    pub memory: Vec<(ContactKey, [f64; 3])>,
    /// The run's own running figures.
    pub extra: T,
}

impl<T> Checkpoint<T> {
    /// The state of `bodies` and `memory` after `step` steps.
    pub fn capture(
        scene: String,
        step: u64,
        time: f64,
        frames: usize,
        bodies: &[Body],
        memory: &ImpulseMemory,
        extra: T,
    ) -> Self {
        Checkpoint {
            format: CHECKPOINT_FORMAT.to_string(),
            scene,
            step,
            time,
            frames,
            bodies: bodies.iter().map(BodyState::of).collect(),
            memory: memory.entries(),
            extra,
        }
    }

    /// Puts the saved state back into `bodies` (built from the same scene); the error
    /// names `path`.
    pub fn restore(&self, path: &Path, bodies: &mut [Body]) -> Result<ImpulseMemory> {
        if self.bodies.len() != bodies.len() {
            return Err(Error::invalid(
                path,
                format!(
                    "the checkpoint has {} bodies, the scene builds {}",
                    self.bodies.len(),
                    bodies.len()
                ),
            ));
        }
        for (body, s) in bodies.iter_mut().zip(&self.bodies) {
            s.apply(body);
        }
        Ok(ImpulseMemory::from_entries(&self.memory))
    }
}

impl<T: Serialize> Checkpoint<T> {
    /// Writes the checkpoint atomically to `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::output::write_checkpoint(path, self)
    }
}

impl<T: DeserializeOwned> Checkpoint<T> {
    /// Reads a checkpoint and checks it was written for `scene` (the merged scene
    /// text); errors are one line naming the file.
    pub fn read(path: &Path, scene: &str) -> Result<Self> {
        crate::output::read_checkpoint_allowing(path, CHECKPOINT_FORMAT, scene, &RUN_CONTROL_KEYS)
    }
}
