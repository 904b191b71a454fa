//! Checkpoints of a `ballast-pack` run, for `ballast-pack --resume DIR` after a run was
//! killed (big beds pack for hours).
//!
//! A [`DepositState`] holds everything the deposition's next step depends on: every
//! body (its role, name, state and inertia, which a sleeper held level or without yaw
//! has partly infinite), the warm-start impulses, the clocks and counters, the random
//! stream, the phases done and the [`Cursor`] that says where in its stages the run
//! stands. The shapes come from the scene again. [`PackCheckpoint`] adds what the run's
//! files need (frames written, the next frame's time, the phase names of
//! `deposit.csv`, the wall time so far) and the merged scene text; it is written and
//! read by [`crate::output::checkpoint`] (`checkpoint.bin`, bincode, atomic rename, tag
//! and scene checked).

use std::path::Path;
use std::time::Duration;

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

use super::deposit::{hold, Cursor, DepositSetup, Deposition, PhaseReport, Role, SleeperModel};
use crate::contact::{ContactKey, ImpulseMemory};
use crate::geometry::random::SplitMix;
use crate::nscd::body::Body;
use crate::nscd::checkpoint::BodyState;
use crate::{Error, Result};

/// The format tag.
pub const PACK_CHECKPOINT_FORMAT: &str = "ballast-pack checkpoint 4";

/// One body of the bed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SavedBody {
    /// What it is (which stone shape, which sleeper).
    pub role: Role,
    /// Its name.
    pub name: String,
    /// Pose and velocities.
    pub state: BodyState,
    /// Principal moments of inertia (kg·m²; infinite about held axes).
    pub inertia: [f64; 3],
    /// A sleeper held where it came to rest (`deposit.hold_sleepers`).
    pub held: bool,
}

/// The deposition between two steps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DepositState {
    /// Every body, boundaries first.
    pub bodies: Vec<SavedBody>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub steps: u64,
    /// Σ over steps of the dynamic bodies.
    pub body_steps: u64,
    /// Wall time per engine phase (s): detect, build, solve, update.
    pub phase_times_s: [f64; 4],
    /// Of the solve: subdomains, interface (s).
    pub solve_split_s: [f64; 2],
    /// Wall time stepping (s).
    pub stepping_s: f64,
    /// Phases done.
    pub phases: Vec<PhaseReport>,
    /// Finishing rules on.
    pub finishing: bool,
    /// The floor vibrating.
    pub vibrating: bool,
    /// The random stream's state.
    pub random: u64,
    /// Stones inserted so far.
    pub inserted: usize,
    /// Where the run stands.
    pub cursor: Cursor,
    /// The warm-start impulses, sorted by key.
    pub memory: Vec<(ContactKey, [f64; 3])>,
    /// The volume of each stone shape of the family (m³, after the scale): the shapes
    /// come from the stone meshes again on resume, and a remeshed family (same count,
    /// new shapes) must not resume silently.
    pub stone_volumes: Vec<f64>,
}

/// A `ballast-pack` checkpoint file's record.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PackCheckpoint {
    /// [`PACK_CHECKPOINT_FORMAT`].
    pub format: String,
    /// The merged scene (after preset and overrides), as TOML text.
    pub scene: String,
    /// The deposition.
    pub bed: DepositState,
    /// VTK frames written.
    pub frames: usize,
    /// Time of the next VTK frame (s).
    pub next_frame: f64,
    /// Phase names in the order of `deposit.csv`'s phase column.
    pub phase_names: Vec<String>,
    /// Wall time of the deposition so far, over every run that led here (s).
    pub wall_s: f64,
}

impl PackCheckpoint {
    /// Writes the checkpoint atomically to `path`.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::output::write_checkpoint(path, self)
    }

    /// Reads a checkpoint and checks it was written for `scene` (the merged scene
    /// text), up to the [`RUN_CONTROL_KEYS`].
    pub fn read(path: &Path, scene: &str) -> Result<Self> {
        crate::output::read_checkpoint_allowing(
            path,
            PACK_CHECKPOINT_FORMAT,
            scene,
            &RUN_CONTROL_KEYS,
        )
    }
}

/// Keys of the merged scene that a resumed run may change: they say how long a phase
/// or a finishing solve may run and how often a checkpoint is taken, not what the bed
/// is. A packing whose final settle sits at the solver's noise floor can so be resumed
/// with a shorter `deposit.max_phase_time` (it ends at that time, reported as not
/// settled), or with a higher `deposit.finish_sweeps`, so that its solves reach the
/// tolerance instead of stopping on the cap (docs/pack.md, "Final settle: the capped
/// solve feeds the bed"), or with a lower `deposit.held_warm_start` when its final
/// settle feeds a self-stress (the strongest contact climbing by orders of magnitude;
/// docs/pack.md, "A third impact bed"). (Changing them makes the resumed run differ
/// from an uninterrupted one with the old values.)
pub const RUN_CONTROL_KEYS: [(&str, &str); 5] = [
    ("deposit", "max_phase_time"),
    ("deposit", "finish_sweeps"),
    ("deposit", "held_warm_start"),
    ("output", "checkpoint_every"),
    ("output", "checkpoint_wall_every"),
];

impl Deposition {
    /// The state a resumed run continues from (taken between two steps).
    pub fn state(&self) -> DepositState {
        let seconds = |d: &Duration| d.as_secs_f64();
        DepositState {
            bodies: self
                .bodies
                .iter()
                .zip(&self.roles)
                .map(|(b, r)| SavedBody {
                    role: *r,
                    name: b.name.clone(),
                    state: BodyState::of(b),
                    inertia: b.inertia.into(),
                    held: matches!(r, Role::Sleeper(_)) && !b.is_dynamic(),
                })
                .collect(),
            time: self.time,
            steps: self.steps,
            body_steps: self.body_steps,
            phase_times_s: self.phase_times.each_ref().map(seconds),
            solve_split_s: self.solve_split.each_ref().map(seconds),
            stepping_s: self.stepping.as_secs_f64(),
            phases: self.phases.clone(),
            finishing: self.finishing,
            vibrating: self.vibrating,
            random: self.random.0,
            inserted: self.inserted,
            cursor: self.cursor.clone(),
            memory: self.engine.memory().entries(),
            stone_volumes: self.setup.family.iter().map(|s| s.shape.volume).collect(),
        }
    }

    /// The deposition of `setup` in `state`; `sleepers` are the models the run lowers
    /// (sleeper k of the state is built from `sleepers[k]`). The error (a checkpoint
    /// that does not fit the scene) is for one line naming the file.
    pub fn restore(
        setup: DepositSetup,
        state: &DepositState,
        sleepers: &[SleeperModel],
    ) -> std::result::Result<Self, String> {
        let family = &setup.family;
        if state.stone_volumes.len() != family.len() {
            return Err(format!(
                "the checkpoint was written with {} stone shapes but stones.directory holds \
                 {} shapes now (the stone meshes changed since the killed run)",
                state.stone_volumes.len(),
                family.len()
            ));
        }
        let changed = family
            .iter()
            .zip(&state.stone_volumes)
            .position(|(s, v)| s.shape.volume.to_bits() != v.to_bits());
        if let Some(k) = changed {
            return Err(format!(
                "stone shape {} ({}) is not the checkpoint's: volume {:.6e} m³ now, {:.6e} m³ \
                 when it was written (the stone meshes changed since the killed run)",
                k + 1,
                family[k].file.display(),
                family[k].shape.volume,
                state.stone_volumes[k]
            ));
        }
        let mut bed = Deposition::new(setup);
        let mut boundaries = std::mem::take(&mut bed.bodies).into_iter();
        bed.roles.clear();
        for saved in &state.bodies {
            let mut body = match saved.role {
                Role::Boundary => boundaries
                    .next()
                    .ok_or("the checkpoint has more boundaries than the scene's container")?,
                Role::Stone(f) => {
                    let stone = bed.setup.family.get(f).ok_or_else(|| {
                        format!(
                            "the checkpoint has a stone of shape {} but stones.directory holds \
                             {} shapes now (the stone meshes changed since the killed run)",
                            f + 1,
                            bed.setup.family.len()
                        )
                    })?;
                    Body::dynamic(
                        &saved.name,
                        stone.shape.clone(),
                        bed.setup.stone_density,
                        bed.setup.stone_material,
                        Isometry3::identity(),
                    )
                }
                Role::Sleeper(k) => {
                    let model = sleepers.get(k).ok_or_else(|| {
                        format!(
                            "the checkpoint has sleeper {}, the scene {}",
                            k + 1,
                            sleepers.len()
                        )
                    })?;
                    // Pose, velocities and inertia are the saved ones.
                    model.body(
                        &saved.name,
                        Isometry3::identity(),
                        bed.setup.sleeper_inertia_scale,
                    )
                }
            };
            saved.state.apply(&mut body);
            if body.is_dynamic() {
                body.inertia = Vector3::from(saved.inertia);
            }
            if saved.held {
                body = hold(&body);
            }
            bed.bodies.push(body);
            bed.roles.push(saved.role);
        }
        if boundaries.next().is_some() {
            return Err("the checkpoint has fewer boundaries than the scene's container".into());
        }
        let duration = |s: &f64| Duration::from_secs_f64(*s);
        bed.time = state.time;
        bed.steps = state.steps;
        bed.body_steps = state.body_steps;
        bed.phase_times = state.phase_times_s.each_ref().map(duration);
        bed.solve_split = state.solve_split_s.each_ref().map(duration);
        bed.stepping = Duration::from_secs_f64(state.stepping_s);
        bed.phases = state.phases.clone();
        bed.finishing = state.finishing;
        bed.engine.options.stopping = Deposition::stopping(&bed.setup, bed.finishing);
        bed.vibrating = state.vibrating;
        bed.random = SplitMix(state.random);
        bed.inserted = state.inserted;
        bed.cursor = state.cursor.clone();
        bed.engine
            .set_memory(ImpulseMemory::from_entries(&state.memory));
        Ok(bed)
    }
}

/// [`Deposition::restore`] with its error naming `path`.
pub fn restore_from(
    path: &Path,
    setup: DepositSetup,
    state: &DepositState,
    sleepers: &[SleeperModel],
) -> Result<Deposition> {
    Deposition::restore(setup, state, sleepers).map_err(|e| Error::invalid(path, e))
}
