//! What `ballast-pack` writes while the bed builds: a `deposit.csv` row every step, the
//! VTK frames of `bed.pvd`, the progress line, and a checkpoint every
//! `output.checkpoint_every` steps or `output.checkpoint_wall_every` of wall time
//! ([`super::resume`]). A resumed run reopens the killed run's `deposit.csv` and
//! `bed.pvd` cut back to the checkpoint's time, so the finished files are the
//! uninterrupted run's.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::deposit::{fastest_point_speed, Deposition, Observer, Role, StepRecord};
use super::resume::{PackCheckpoint, PACK_CHECKPOINT_FORMAT};
use crate::nscd::body::Body;
use crate::nscd::run::{grains_grid, Drawn};
use crate::output::{Cadence, CsvSeries, Grid, Progress, PvdWriter};
use crate::{Error, Result};

/// Columns of `deposit.csv`. `energy_rise_J` is the step's ΔKE − work of gravity and
/// of the driven bodies: ≤ 0 for a converged Moreau–Jean step (θ = 1) whose contacts
/// only dissipate; overlaps pushed open at the depenetration speed and a solve stopped
/// on its sweep cap can make it positive (docs/pack.md, "Final settle: the capped solve
/// feeds the bed"). `fastest_point_m_s` is the settle test's fastest body point
/// ([`fastest_point_speed`]).
const COLUMNS: [&str; 11] = [
    "time_s",
    "phase",
    "stones",
    "contacts",
    "nlgs_sweeps",
    "nlgs_error",
    "kinetic_energy_J",
    "max_interpenetration_m",
    "max_contact_force_N",
    "energy_rise_J",
    "fastest_point_m_s",
];

/// When and where checkpoints go.
#[derive(Debug, Clone)]
pub struct CheckpointPlan {
    /// `checkpoint.bin` in the output directory.
    pub path: PathBuf,
    /// When (every so many steps, after so much wall time).
    pub cadence: Cadence,
    /// The merged scene text the checkpoint is tied to.
    pub scene: String,
}

/// What tells a self-stress from the bed's own load: on its way to rest a bed's
/// contact carries about the weight of what lies on it (wedging and arching multiply it
/// by a few at most), so one that carries more than the whole bed's weight holds a
/// self-stress, which a fully warm-started solve can feed until the bed creeps or is
/// thrown up (docs/nscd.md, "Warm start and self-stress";
/// docs/pack.md, "A third impact bed").
#[derive(Debug, Clone, Copy)]
pub struct WeightWatch {
    /// The sleepers' true weight (N), whatever inertia they are packed with.
    pub sleepers_n: f64,
    /// |g| (m/s²).
    pub gravity: f64,
    /// `deposit.held_warm_start`, named in the note.
    pub held_warm_start: f64,
}

impl WeightWatch {
    /// The bed's weight (N): its stones' and its sleepers' (true).
    pub fn bed_weight(&self, bodies: &[Body], roles: &[Role]) -> f64 {
        let stones: f64 = bodies
            .iter()
            .zip(roles)
            .filter(|(_, r)| matches!(r, Role::Stone(_)))
            .map(|(b, _)| b.mass)
            .sum();
        stones * self.gravity + self.sleepers_n
    }

    /// The note for a finishing step whose strongest contact carries more than the
    /// bed's weight (`None` for any other step); with held sleepers it names the two
    /// keys that bear on it (`deposit.hold_sleepers`, `deposit.held_warm_start`).
    pub fn note(&self, record: &StepRecord, bodies: &[Body], roles: &[Role]) -> Option<String> {
        let force = record.report.max_contact_force;
        // The sleepers' weight first: the bed's sum is only taken for a strong contact.
        if !record.finishing || force <= self.sleepers_n {
            return None;
        }
        let weight = self.bed_weight(bodies, roles);
        if force <= weight {
            return None;
        }
        let held = bodies
            .iter()
            .zip(roles)
            .any(|(b, r)| matches!(r, Role::Sleeper(_)) && !b.is_dynamic());
        let remedy = if held {
            format!(
                " Held sleepers bound such columns (the release, when on, settles the \
                 bed again without them); a bed built with deposit.hold_sleepers = false \
                 (free sleepers carrying 1/k of their weight) has none (docs/pack.md, \
                 \"Held sleepers: the quick beds\"); resumed from a checkpoint before this \
                 with a lower deposit.held_warm_start (now {}), the stress stays bounded \
                 but the phase may still not settle.",
                self.held_warm_start
            )
        } else {
            String::new()
        };
        Some(format!(
            "ballast-pack: {}, t = {:.3} s: a contact carries {:.2} kN, more than the whole \
             bed's weight ({:.2} kN): a self-stress that the warm start feeds (docs/nscd.md, \
             \"Warm start and self-stress\").{remedy}",
            record.phase,
            record.time,
            1e-3 * force,
            1e-3 * weight
        ))
    }
}

/// The deposition's files as it runs (an [`Observer`]).
pub struct Recorder {
    csv: CsvSeries,
    pvd: PvdWriter,
    frame_interval: f64,
    next_frame: f64,
    /// Frames written.
    frames: usize,
    phase_names: Vec<String>,
    /// The first error met (a file that could not be written): nothing more is
    /// written, the deposition stops ([`Observer::stop`]), and [`Self::finish`]
    /// returns it.
    failure: Option<Error>,
    bar: Progress,
    checkpoints: CheckpointPlan,
    /// Wall time of the runs before a resume.
    wall_before: Duration,
    clock: Instant,
    /// Wall time spent writing checkpoints.
    pub checkpoint_time: Duration,
    watch: WeightWatch,
    /// The phases whose self-stress has been noted (once each).
    noted: Vec<String>,
}

impl Recorder {
    /// New files in `dir`, or (`resumed`) the killed run's files cut back to the
    /// checkpoint, with its counters.
    pub fn open(
        dir: &Path,
        frame_interval: f64,
        checkpoints: CheckpointPlan,
        watch: WeightWatch,
        resumed: Option<&PackCheckpoint>,
    ) -> Result<Self> {
        let csv_path = dir.join("deposit.csv");
        let pvd_path = dir.join("bed.pvd");
        let (csv, pvd) = match resumed {
            Some(c) => (
                CsvSeries::open_existing(csv_path, &COLUMNS, c.bed.time)?,
                PvdWriter::open_existing(pvd_path, c.bed.time)?,
            ),
            None => (
                CsvSeries::create(csv_path, &COLUMNS)?,
                PvdWriter::create(pvd_path)?,
            ),
        };
        let bar = Progress::spinner("ballast-pack");
        Ok(Recorder {
            csv,
            pvd,
            frame_interval,
            next_frame: resumed.map_or(0.0, |c| c.next_frame),
            frames: resumed.map_or(0, |c| c.frames),
            phase_names: resumed.map_or_else(Vec::new, |c| c.phase_names.clone()),
            failure: None,
            bar,
            checkpoints,
            wall_before: Duration::from_secs_f64(resumed.map_or(0.0, |c| c.wall_s)),
            clock: Instant::now(),
            checkpoint_time: Duration::ZERO,
            watch,
            noted: Vec::new(),
        })
    }

    /// Notes, once per phase, a finishing step whose strongest contact carries more
    /// than the bed's weight ([`WeightWatch::note`]).
    fn watch_self_stress(&mut self, record: &StepRecord, bodies: &[Body], roles: &[Role]) {
        if self.noted.iter().any(|p| p == record.phase) {
            return;
        }
        if let Some(note) = self.watch.note(record, bodies, roles) {
            self.noted.push(record.phase.to_string());
            self.bar.note(&note);
        }
    }

    /// Wall time of the deposition so far, the runs before a resume included.
    pub fn wall(&self) -> Duration {
        self.wall_before + self.clock.elapsed()
    }

    /// Clears the progress line; the first error met, if any.
    pub fn finish(&mut self) -> Result<()> {
        self.bar.finish_and_clear();
        self.failure.take().map_or(Ok(()), Err)
    }

    /// Writes the next frame, `frames/bed_NNNN.vtu`, at `time` (the final bed too).
    pub fn frame(&mut self, time: f64, bodies: &[Body], roles: &[Role]) -> Result<()> {
        let name = format!("frames/bed_{:04}.vtu", self.frames);
        self.pvd
            .write_frame(time, &name, &bed_grid(bodies, roles)?)?;
        self.frames += 1;
        Ok(())
    }

    fn checkpoint(&mut self, bed: &Deposition) -> Result<()> {
        let clock = Instant::now();
        PackCheckpoint {
            format: PACK_CHECKPOINT_FORMAT.to_string(),
            scene: self.checkpoints.scene.clone(),
            bed: bed.state(),
            frames: self.frames,
            next_frame: self.next_frame,
            phase_names: self.phase_names.clone(),
            wall_s: self.wall().as_secs_f64(),
        }
        .write(&self.checkpoints.path)?;
        self.checkpoint_time += clock.elapsed();
        Ok(())
    }
}

impl Observer for Recorder {
    fn step(&mut self, record: &StepRecord, bodies: &[Body], roles: &[Role]) {
        if self.failure.is_some() {
            return;
        }
        let phase = match self.phase_names.iter().position(|p| p == record.phase) {
            Some(k) => k,
            None => {
                self.phase_names.push(record.phase.to_string());
                self.phase_names.len() - 1
            }
        };
        let r = record.report;
        let row = [
            record.time,
            phase as f64,
            record.stones as f64,
            r.contacts as f64,
            r.nlgs.iterations as f64,
            r.nlgs.error,
            r.kinetic_energy,
            r.max_interpenetration,
            r.max_contact_force,
            r.energy_rise,
            fastest_point_speed(bodies),
        ];
        if let Err(e) = self.csv.push(&row) {
            self.failure = Some(e);
            return;
        }
        self.watch_self_stress(record, bodies, roles);
        if self.frame_interval > 0.0 && record.time >= self.next_frame {
            self.next_frame = record.time + self.frame_interval;
            if let Err(e) = self.frame(record.time, bodies, roles) {
                self.failure = Some(e);
                return;
            }
        }
        self.bar.set_message(format!(
            "{}: t = {:.2} s, {} stones, KE {:.2e} J, {} contacts",
            record.phase, record.time, record.stones, r.kinetic_energy, r.contacts
        ));
    }

    fn between_steps(&mut self, bed: &Deposition) {
        if self.failure.is_some() || !self.checkpoints.cadence.due(bed.steps) {
            return;
        }
        if let Err(e) = self.checkpoint(bed) {
            self.failure = Some(e);
        }
        self.checkpoints.cadence.written();
    }

    fn stop(&self) -> bool {
        self.failure.is_some()
    }
}

/// Stones and sleepers in one grid, cell field `sleeper` (1 on sleepers).
pub fn bed_grid(bodies: &[Body], roles: &[Role]) -> Result<Grid> {
    let mut grid = grains_grid(bodies, Drawn::All, &[])?;
    let kinds: Vec<i32> = bodies
        .iter()
        .zip(roles)
        .filter(|(b, _)| b.shape.collider.is_bounded())
        .flat_map(|(b, r)| {
            std::iter::repeat_n(
                i32::from(matches!(r, Role::Sleeper(_))),
                b.shape.triangles.len(),
            )
        })
        .collect();
    grid.add_cell_field("sleeper", 1, kinds)?;
    Ok(grid)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nscd::body::{BodyShape, Motion};
    use crate::nscd::step::StepReport;
    use nalgebra::{Isometry3, Vector3};
    use std::sync::Arc;

    /// A 0.1 m granite cube (2.7 kg) and a 0.2 m concrete sleeper held where it is,
    /// whose true weight the watch is given (188.4 N): the bed weighs 214.8 N.
    fn bed() -> (Vec<Body>, Vec<Role>, WeightWatch) {
        let cube = |size: f64| Arc::new(BodyShape::cuboid(Vector3::repeat(size)).unwrap());
        let stone = Body::dynamic("stone", cube(0.1), 2700.0, 0, Isometry3::identity());
        let sleeper = Body::fixed(
            "sleeper",
            cube(0.2),
            1,
            Isometry3::identity(),
            Motion::Static,
        );
        let watch = WeightWatch {
            sleepers_n: 2400.0 * 0.008 * 9.81,
            gravity: 9.81,
            held_warm_start: 1.0,
        };
        (
            vec![stone, sleeper],
            vec![Role::Stone(0), Role::Sleeper(0)],
            watch,
        )
    }

    /// The note comes for a finishing step whose strongest contact carries more than
    /// the bed's weight, stones and sleepers (true) together, and names the phase, the
    /// force, the weight and, the sleepers being held, the warm-start key; not for a
    /// contact just under the weight, nor for any contact while the bed is raining.
    #[test]
    fn a_contact_stronger_than_the_bed_is_noted_while_finishing() {
        let (bodies, roles, watch) = bed();
        let weight = 2.7 * 9.81 + 2400.0 * 0.008 * 9.81;
        assert!((watch.bed_weight(&bodies, &roles) - weight).abs() < 1e-9);
        let note = |force: f64, finishing: bool, bodies: &[Body]| {
            let report = StepReport {
                max_contact_force: force,
                ..StepReport::default()
            };
            let record = StepRecord {
                time: 6.9,
                phase: "final settle",
                stones: 1,
                finishing,
                report: &report,
            };
            watch.note(&record, bodies, &roles)
        };
        assert_eq!(note(0.99 * weight, true, &bodies), None);
        assert_eq!(note(100.0 * weight, false, &bodies), None);
        let line = note(1.01 * weight, true, &bodies).expect("a note");
        for part in [
            "final settle, t = 6.900 s",
            "0.22 kN, more than the whole bed's weight (0.21 kN)",
            "deposit.hold_sleepers = false",
            "deposit.held_warm_start (now 1)",
        ] {
            assert!(line.contains(part), "{line}");
        }
        // A free sleeper bounds no column: the note names no sleeper key then.
        let mut free = bodies.clone();
        free[1] = Body::dynamic(
            "sleeper",
            bodies[1].shape.clone(),
            2400.0,
            1,
            Isometry3::identity(),
        );
        let line = note(1.01 * weight, true, &free).expect("a note");
        assert!(!line.contains("deposit."), "{line}");
    }
}
