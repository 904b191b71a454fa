//! `ballast-qdem SCENE.toml` for a scene with a `[track]` table: the sleeper on
//! ballast under rail-seat loads (seed 004 §4).
//!
//! Output directory:
//! Times in both CSVs are on the load file's clock: 0 at the end of settling (negative
//! while settling in `track.csv`; `sensors.csv` starts at 0).
//! - `sensors.csv`: `time_s`, then per sensor `NAME_u{x,y,z}_m`, `NAME_v{x,y,z}_m_per_s`,
//!   `NAME_a{x,y,z}_m_per_s2` at the sampling rate (seed 004: 10 kHz); what
//!   `ballast-post spectra` reads;
//! - `track.csv`: at the same rate, the applied rail-seat loads, the sleeper's
//!   settlement (mean vertical displacement of its bottom face), contacts, deepest
//!   sphere overlap, and the energy terms with the balance error;
//! - `deformable.pvd` (sleeper and deformable stones: tetra with displacement,
//!   velocity, body, von Mises stress) and `rigid.pvd` (rigid stones' surfaces with
//!   displacement, velocity, body);
//! - `summary.json`: counts, stable and used steps, settlement, overlaps, energy
//!   balance, throughput (contact pairs/s, tetra updates/s, simulated seconds per wall
//!   hour), peak memory, wall time per phase.

use std::time::Instant;

use serde::{Deserialize, Serialize};
use serde_json::json;

use super::build::{build, SensorAt, Track};
use super::loads::RailSeatLoads;
use super::scene::{DtSpec, TrackScene};
use crate::dem::{MultiBodySolver, MultiState};
use crate::output::{
    read_checkpoint_allowing, write_checkpoint, write_json, Cadence, CsvSeries, Grid, Progress,
    PvdWriter, RunClocks, CHECKPOINT_FILE,
};
use crate::pack::Packing;
use crate::post::track_sensors::QUANTITIES;
use crate::qdem::von_mises;
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::solid::qdem_run::say;
use crate::{Error, Result};

/// Whether a scene file is a track scene (has a `[track]` table).
pub fn is_track_scene(scene: &std::path::Path) -> bool {
    std::fs::read_to_string(scene)
        .ok()
        .and_then(|t| t.parse::<toml::Table>().ok())
        .is_some_and(|t| t.contains_key("track"))
}

/// Runs the track scene of `ctx`; `force` allows a step above the stable one; with
/// `resume`, from the checkpoint in the output directory (written by a run of the same
/// scene, preset and overrides), cutting the CSV and `.pvd` series back to it.
pub fn run(ctx: &RunContext, force: bool, resume: bool) -> Result<()> {
    let threads = ctx.configure_threads()?;
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (TrackScene, _) = timer.time("read scene", || ctx.load_scene())?;
    let scene_text = toml::to_string(&inputs)
        .map_err(|e| Error::Message(format!("cannot write the merged scene: {e}")))?;
    let resumed: Option<TrackCheckpoint> = if resume {
        let path = ctx.out_dir.join(CHECKPOINT_FILE);
        Some(read_checkpoint_allowing(
            &path,
            CHECKPOINT_FORMAT,
            &scene_text,
            &RUN_CONTROL_KEYS,
        )?)
    } else {
        None
    };
    let packing_path = TrackScene::resolve(&ctx.scene_path, &scene.track.packing);
    let packing = Packing::read(&packing_path)?;
    if let Some(note) = packing.unsettled_note("ballast-qdem", &packing_path) {
        println!("{note}");
    }
    let loads = match &scene.track.loads {
        Some(file) => {
            let path = TrackScene::resolve(&ctx.scene_path, file);
            let loads = RailSeatLoads::read(&path)?;
            // Past its last row a record would hold its last value: refuse instead.
            let (end, wanted) = (
                *loads.times.last().unwrap_or(&0.0),
                scene.track.duration.si(),
            );
            if wanted > end * (1.0 + 1e-9) + 1e-12 {
                return Err(Error::invalid(
                    &path,
                    format!(
                        "the record ends at t = {end} s, before the end of track.duration = \
                         {wanted} s (write a longer record, or shorten the run)"
                    ),
                ));
            }
            Some(loads)
        }
        None => None,
    };
    let track = timer.time("build", || {
        build(
            &ctx.scene_path,
            &scene,
            &packing_path,
            &packing,
            loads.as_ref(),
        )
    })?;
    std::fs::create_dir_all(&ctx.out_dir).map_err(|e| Error::io(&ctx.out_dir, e))?;
    let sys = &track.system;
    say(format_args!(
        "ballast-qdem: track on {} — sleeper + {} stones ({} deformable, {} rigid), {} tetra, {} spheres, {threads} threads",
        packing_path.display(),
        packing.stones.len(),
        track.deformable_stones,
        sys.rigid.len(),
        sys.tet_count(),
        sys.spheres.len(),
    ));

    // Time step: the sampling period cut into whole steps.
    let t = &scene.track;
    let period = 1.0 / t.sample_rate.si();
    let mut state = sys.at_rest();
    let mut solver = MultiBodySolver::new(sys, period, t.skin.si())?;
    let stable = timer.time("stable step", || solver.stability(&mut state));
    let dt = match t.dt {
        None | Some(DtSpec::Auto) => period / (period / (t.dt_factor * stable.stable())).ceil(),
        Some(DtSpec::Fixed(dt)) => dt.si(),
    };
    say(format_args!(
        "ballast-qdem: stable time step {:.4e} s (tetra {:.4e} s, contact springs {:.4e} s); dt = {dt:.4e} s",
        stable.stable(),
        stable.tetra,
        stable.contact
    ));
    if dt > stable.stable() && !force {
        return Err(Error::invalid(
            &ctx.scene_path,
            format!(
                "track.dt = {dt:.4e} s exceeds the stable time step {:.4e} s (use dt = \"auto\", or --force)",
                stable.stable()
            ),
        ));
    }
    let mut solver = MultiBodySolver::new(sys, dt, t.skin.si())?;
    solver.stability(&mut state);
    let sample_every = ((period / dt).round() as u64).max(1);
    let settle_steps = (t.settle.si() / dt).round() as u64;
    let total_steps = settle_steps + (t.duration.si() / dt).ceil() as u64;
    let frame_every = (total_steps / t.frames.max(1) as u64).max(1);

    let settled = settle_steps as f64 * dt;
    let checkpoint_path = ctx.out_dir.join(CHECKPOINT_FILE);
    let mut figures = LoopFigures {
        kinetic_after_settling: state.kinetic(),
        ..LoopFigures::default()
    };
    // Wall time of the pieces before this one (a resumed run), from the clocks beside
    // the checkpoint.
    let mut before = RunClocks::default();
    let mut clocks_known = true;
    let mut out = match resumed {
        Some(c) => {
            // The scene text matched; the packing it names must still give these bodies.
            let nodes = |s: &MultiState| s.deformable.as_ref().map_or(0, |d| d.positions.len());
            if c.state.rigid.len() != state.rigid.len()
                || nodes(&c.state) != nodes(&state)
                || c.state.contacts.anchors.len() != sys.spheres.len()
            {
                return Err(Error::invalid(
                    &checkpoint_path,
                    format!(
                        "holds {} rigid bodies and {} nodes, the scene now builds {} and {} \
                         (was the packing {} rewritten?)",
                        c.state.rigid.len(),
                        nodes(&c.state),
                        state.rigid.len(),
                        nodes(&state),
                        packing_path.display()
                    ),
                ));
            }
            match RunClocks::resume(&ctx.out_dir, c.state.step, &mut timer) {
                Ok(clocks) => before = clocks,
                Err(note) => {
                    clocks_known = false;
                    say(format_args!("ballast-qdem: {note}"));
                }
            }
            let clock = c.state.step as f64 * dt - settled;
            let out = Outputs::open(ctx, &track, Some((clock, c.state.time, c.frames)))?;
            state = c.state;
            solver.resume(&state, c.memory);
            figures = c.figures;
            say(format_args!(
                "ballast-qdem: resumed from {} at step {} (t = {:.6} s)",
                checkpoint_path.display(),
                state.step,
                state.time
            ));
            out
        }
        None => {
            let mut out = Outputs::open(ctx, &track, None)?;
            out.record(&track, &state, &solver, loads.as_ref(), settled)?;
            out.frame(&track, &state)?;
            out
        }
    };
    let started = Instant::now();
    // Stepping time since `started`: its clock less the frames written since (those
    // written before it, the first one, are not in that clock).
    let frames_at_start = out.frame_s;
    let stepping_since =
        |frame_s: f64| started.elapsed().as_secs_f64() - (frame_s - frames_at_start);
    let mut cadence = Cadence::new(t.checkpoint_every, t.checkpoint_wall_every);
    let (first_step, touching_before) = (state.step, figures.touching_sum);
    let mut bar = Progress::steps(total_steps, "ballast-qdem: track");
    bar.set_position(state.step);
    solver.set_damping(if state.step < settle_steps {
        t.settle_damping.si()
    } else {
        0.0
    })?;
    while state.step < total_steps {
        if state.step == settle_steps && settle_steps > 0 {
            solver.set_damping(0.0)?;
            figures.settled_at = out.settlement(&track, &state);
            figures.kinetic_after_settling = state.kinetic();
            figures.sinking_after_settling = out.sleeper_velocity(&track, &state);
            timer.add("settling", started.elapsed());
        }
        solver.step(&mut state)?;
        figures.touching_sum += (solver.last.touching + solver.last.touching_planes) as u64;
        figures.max_overlap = figures.max_overlap.max(solver.last.max_overlap);
        if state.step % sample_every == 0 {
            out.record(&track, &state, &solver, loads.as_ref(), settled)?;
        }
        if state.step % frame_every == 0 || state.step == total_steps {
            out.frame(&track, &state)?;
        }
        if cadence.due(state.step) || (t.checkpoint_every > 0 && state.step == total_steps) {
            let clock = Instant::now();
            write_checkpoint(
                &checkpoint_path,
                &TrackCheckpoint {
                    format: CHECKPOINT_FORMAT.to_string(),
                    scene: scene_text.clone(),
                    state: state.clone(),
                    memory: solver.memory(),
                    figures,
                    frames: out.frames,
                },
            )?;
            cadence.written();
            out.frame_s += clock.elapsed().as_secs_f64();
            let stepping = stepping_since(out.frame_s);
            before
                .then(state.step, stepping, out.frame_s, &timer)
                .write(&ctx.out_dir)?;
        }
        if state.step % 256 == 0 {
            bar.set_message(format!("t = {:.4} s", state.time));
            bar.set_position(state.step);
        }
    }
    bar.finish_and_clear();
    let stepping = stepping_since(out.frame_s);
    let run_stepping = before.stepping_s + stepping;
    timer.add("stepping", std::time::Duration::from_secs_f64(run_stepping));
    timer.add(
        "frames and checkpoints",
        std::time::Duration::from_secs_f64(before.frames_s + out.frame_s),
    );
    // Throughput of this process's steps (a resumed run counts from its checkpoint);
    // the wall times cover every piece of the run.
    let touching_sum = figures.touching_sum - touching_before;
    let steps_here = (state.step - first_step) as f64;
    let LoopFigures {
        max_overlap,
        settled_at,
        kinetic_after_settling,
        sinking_after_settling,
        ..
    } = figures;

    let settlement = out.settlement(&track, &state) - settled_at;
    let simulated = state.time;
    let balance = state.balance_error();
    let scale = state
        .external_work()
        .abs()
        .max(state.mechanical())
        .max(state.dissipated());
    let summary = Summary::new(ctx, &inputs)
        .figure("stones", packing.stones.len())
        .figure("deformable_stones", track.deformable_stones)
        .figure("rigid_stones", sys.rigid.len())
        .figure("tetra", sys.tet_count())
        .figure("spheres", sys.spheres.len())
        .figure(
            "sphere_diameter_min_m",
            2.0 * sys.set.radius.iter().fold(f64::INFINITY, |a, &b| a.min(b)),
        )
        .figure("sphere_diameter_max_m", 2.0 * sys.set.max_radius())
        .figure("stable_dt_s", stable.stable())
        .figure("stable_dt_tetra_s", stable.tetra)
        .figure("stable_dt_contact_s", stable.contact)
        .figure("dt_s", dt)
        .figure("steps", state.step)
        .figure("simulated_s", simulated)
        .figure("sample_rate_hz", 1.0 / (sample_every as f64 * dt))
        .figure("sleeper_settlement_m", settlement)
        .figure("settling_sink_m", settled_at)
        .figure("kinetic_energy_after_settling_j", kinetic_after_settling)
        .figure(
            "sleeper_velocity_after_settling_m_per_s",
            sinking_after_settling,
        )
        .figure("max_overlap_m", max_overlap)
        .figure("final_max_overlap_m", solver.last.max_overlap)
        .figure("final_mean_overlap_m", solver.last.mean_overlap)
        .figure("stone_size_m", track.stone_size)
        .figure(
            "final_contacts",
            solver.last.touching + solver.last.touching_planes,
        )
        .figure("energy_balance_error_j", balance)
        .figure(
            "energy_balance_relative",
            if scale > 0.0 {
                balance.abs() / scale
            } else {
                0.0
            },
        )
        .figure("contact_pairs_per_s", touching_sum as f64 / stepping)
        .figure(
            "tetra_updates_per_s",
            steps_here * sys.tet_count() as f64 / stepping,
        )
        .figure(
            "simulated_s_per_wall_hour",
            steps_here * dt / stepping * 3600.0,
        )
        .figure("stepping_s", stepping)
        .figure("run_stepping_s", run_stepping)
        .figure("pieces", before.pieces + 1)
        .figure("wall_times_complete", clocks_known)
        .figure("list_rebuilds", state.contacts.rebuilds)
        .figure("candidate_pairs", solver.last.candidates)
        .figure("peak_memory_mib", peak_memory_mib())
        .figure(
            "sensors",
            json!(track
                .sensors
                .iter()
                .map(|s| s.name.clone())
                .collect::<Vec<_>>()),
        )
        .wall_times(&timer);
    write_json(ctx.out_dir.join("summary.json"), &summary.to_json())?;
    say(format_args!(
        "ballast-qdem: {} steps ({simulated:.4} s) in {stepping:.1} s — {:.3e} contact pairs/s, {:.3e} tetra updates/s, {:.3} simulated s per wall hour",
        state.step - first_step,
        touching_sum as f64 / stepping,
        steps_here * sys.tet_count() as f64 / stepping,
        steps_here * dt / stepping * 3600.0
    ));
    say(format_args!(
        "ballast-qdem: sleeper settlement {:.3e} m; deepest sphere overlap {max_overlap:.3e} m; energy balance error {:.2e} of the energy scale",
        settlement,
        if scale > 0.0 { balance.abs() / scale } else { 0.0 }
    ));
    say(format_args!(
        "wrote {}",
        ctx.out_dir.join("summary.json").display()
    ));
    Ok(())
}

/// The columns of `track.csv`.
const TRACK_COLUMNS: [&str; 12] = [
    "time_s",
    "rp1_n",
    "rp2_n",
    "sleeper_settlement_m",
    "contacts",
    "max_overlap_m",
    "kinetic_j",
    "strain_j",
    "spring_j",
    "dissipated_j",
    "external_work_j",
    "balance_error_j",
];

/// The format tag of a track checkpoint (3: the meshes' nodes in locality order, so a
/// checkpoint of an earlier build would restore its states onto other nodes).
const CHECKPOINT_FORMAT: &str = "ballast-qdem track checkpoint 3";

/// Keys of the merged scene a resumed run may change: how often it checkpoints, not
/// what it computes ([`crate::output::read_checkpoint_allowing`]).
const RUN_CONTROL_KEYS: [(&str, &str); 2] = [
    ("track", "checkpoint_every"),
    ("track", "checkpoint_wall_every"),
];

/// Everything a killed track run needs to go on bit for bit (written by
/// [`write_checkpoint`]; the scene, bodies and loads come from the scene again).
#[derive(Serialize, Deserialize)]
struct TrackCheckpoint {
    /// [`CHECKPOINT_FORMAT`].
    format: String,
    /// The merged scene (after preset and overrides), as TOML text.
    scene: String,
    /// The system after the checkpoint's step.
    state: MultiState,
    /// [`MultiBodySolver::memory`].
    memory: Vec<[f64; 3]>,
    /// The run's running figures.
    figures: LoopFigures,
    /// VTK frames written (the initial one included).
    frames: usize,
}

/// Running figures of the time loop that go into the summary.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
struct LoopFigures {
    /// Σ over steps of the touching pairs (for contact pairs per second).
    touching_sum: u64,
    /// Deepest sphere overlap seen (m).
    max_overlap: f64,
    /// Sleeper settlement at the end of settling (m).
    settled_at: f64,
    /// Kinetic energy at the end of settling (J).
    kinetic_after_settling: f64,
    /// Sleeper's vertical velocity at the end of settling (m/s).
    sinking_after_settling: f64,
}

/// The files of a run.
struct Outputs {
    sensors: CsvSeries,
    track: CsvSeries,
    deformable: PvdWriter,
    rigid: PvdWriter,
    frames: usize,
    frame_s: f64,
}

impl Outputs {
    /// New files, or (`resume`: the checkpoint's clock, time and frame count) the
    /// killed run's files cut back to the checkpoint.
    fn open(ctx: &RunContext, track: &Track, resume: Option<(f64, f64, usize)>) -> Result<Self> {
        let mut columns = vec!["time_s".to_string()];
        // The columns `ballast-post spectra` reads, in its order (u, v, a; x, y, z).
        for s in &track.sensors {
            columns.extend(QUANTITIES.iter().map(|q| format!("{}_{q}", s.name)));
        }
        let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
        let dir = &ctx.out_dir;
        // Both CSVs are on the clock (0 at the end of settling), the .pvd on run time.
        let csv = |name: &str, columns: &[&str]| match resume {
            Some((clock, _, _)) => CsvSeries::open_existing(dir.join(name), columns, clock),
            None => CsvSeries::create(dir.join(name), columns),
        };
        let pvd = |name: &str| match resume {
            Some((_, time, _)) => PvdWriter::open_existing(dir.join(name), time),
            None => PvdWriter::create(dir.join(name)),
        };
        std::fs::create_dir_all(dir.join("frames")).map_err(|e| Error::io(dir, e))?;
        Ok(Outputs {
            sensors: csv("sensors.csv", &refs)?,
            track: csv("track.csv", &TRACK_COLUMNS)?,
            deformable: pvd("deformable.pvd")?,
            rigid: pvd("rigid.pvd")?,
            frames: resume.map_or(0, |(_, _, frames)| frames),
            frame_s: 0.0,
        })
    }

    fn settlement(&self, track: &Track, state: &MultiState) -> f64 {
        let Some(s) = &state.deformable else {
            return 0.0;
        };
        let model = track.system.model.as_ref().expect("the sleeper deforms");
        let r = model.reference_positions();
        let n = track.sleeper_bottom.len().max(1) as f64;
        track
            .sleeper_bottom
            .iter()
            .map(|&i| s.positions[i as usize][2] - r[i as usize][2])
            .sum::<f64>()
            / n
    }

    /// Mean vertical velocity of the sleeper's bottom nodes (m/s).
    fn sleeper_velocity(&self, track: &Track, state: &MultiState) -> f64 {
        let Some(s) = &state.deformable else {
            return 0.0;
        };
        let n = track.sleeper_bottom.len().max(1) as f64;
        track
            .sleeper_bottom
            .iter()
            .map(|&i| s.velocities[i as usize][2])
            .sum::<f64>()
            / n
    }

    fn record(
        &mut self,
        track: &Track,
        state: &MultiState,
        solver: &MultiBodySolver<'_>,
        loads: Option<&RailSeatLoads>,
        settle: f64,
    ) -> Result<()> {
        let sys = &track.system;
        // From the step count, so that the end of settling is exactly 0.
        let clock = state.step as f64 * solver.dt() - settle;
        let mut row = vec![clock];
        let g = sys.gravity;
        for sensor in &track.sensors {
            let (u, v, a) = match &sensor.at {
                SensorAt::Node(i) => {
                    let s = state.deformable.as_ref().expect("sleeper");
                    let r = sys.model.as_ref().expect("sleeper").reference_positions()[*i as usize];
                    let x = s.positions[*i as usize];
                    (
                        [x[0] - r[0], x[1] - r[1], x[2] - r[2]],
                        s.velocities[*i as usize],
                        s.accelerations[*i as usize],
                    )
                }
                SensorAt::DeformableStone(range) => {
                    let s = state.deformable.as_ref().expect("deformable stone");
                    let model = sys.model.as_ref().expect("deformable stone");
                    let (m, r) = (model.node_masses(), model.reference_positions());
                    let mut acc = [[0.0; 3]; 3];
                    let mut total = 0.0;
                    for i in range.clone().map(|i| i as usize) {
                        total += m[i];
                        for d in 0..3 {
                            acc[0][d] += m[i] * (s.positions[i][d] - r[i][d]);
                            acc[1][d] += m[i] * s.velocities[i][d];
                            acc[2][d] += m[i] * s.accelerations[i][d];
                        }
                    }
                    let mean = |v: [f64; 3]| v.map(|c| c / total);
                    (mean(acc[0]), mean(acc[1]), mean(acc[2]))
                }
                SensorAt::RigidStone(b) => {
                    let (r, shape) = (&state.rigid[*b as usize], &sys.rigid[*b as usize]);
                    let u = [0, 1, 2].map(|d| r.position[d] - shape.centre[d]);
                    let a = [0, 1, 2].map(|d| r.force[d] / shape.mass + g[d]);
                    (u, r.velocity, a)
                }
            };
            row.extend_from_slice(&u);
            row.extend_from_slice(&v);
            row.extend_from_slice(&a);
        }
        if clock >= 0.0 {
            self.sensors.push(&row)?;
        }
        let (rp1, rp2) = match loads {
            Some(l) if clock >= 0.0 => l.at(clock),
            _ => (0.0, 0.0),
        };
        let strain = state.deformable.as_ref().map_or(0.0, |s| s.energies.strain);
        self.track.push(&[
            clock,
            rp1,
            rp2,
            self.settlement(track, state),
            (solver.last.touching + solver.last.touching_planes) as f64,
            solver.last.max_overlap,
            state.kinetic(),
            strain,
            state.energies.spring,
            state.dissipated(),
            state.external_work(),
            state.balance_error(),
        ])
    }

    fn frame(&mut self, track: &Track, state: &MultiState) -> Result<()> {
        let started = Instant::now();
        let sys = &track.system;
        let k = self.frames;
        if let (Some(s), Some(model)) = (&state.deformable, &sys.model) {
            let tets: Vec<[usize; 4]> = track.tets.iter().map(|t| t.map(|n| n as usize)).collect();
            let mut grid = Grid::tetra(s.positions.clone(), &tets)?;
            let r = model.reference_positions();
            let u: Vec<f64> = s
                .positions
                .iter()
                .zip(r)
                .flat_map(|(x, r)| [x[0] - r[0], x[1] - r[1], x[2] - r[2]])
                .collect();
            grid.add_point_field("displacement_m", 3, u)?;
            grid.add_point_field("velocity_m_per_s", 3, s.velocities.concat())?;
            grid.add_cell_field(
                "body",
                1,
                track.tet_body.iter().map(|&b| b as i32).collect::<Vec<_>>(),
            )?;
            let vm: Vec<f64> = model
                .stresses(&s.positions, &s.velocities)
                .iter()
                .map(von_mises)
                .collect();
            grid.add_cell_field("von_mises_Pa", 1, vm)?;
            self.deformable.write_frame(
                state.time,
                format!("frames/deformable_{k:04}.vtu"),
                &grid,
            )?;
        }
        // Rigid stones: their surfaces at the current pose.
        let mut points = Vec::new();
        let mut tris = Vec::new();
        let mut body = Vec::new();
        let mut disp = Vec::new();
        let mut vel = Vec::new();
        let rigid_ids: Vec<i32> = sys
            .bodies
            .iter()
            .enumerate()
            .filter(|(_, k)| matches!(k, crate::dem::BodyKind::Rigid { .. }))
            .map(|(id, _)| id as i32)
            .collect();
        for (b, (r, shape)) in state.rigid.iter().zip(&sys.rigid).enumerate() {
            let offset = points.len();
            let q = r.rotation();
            let w = r.angular_velocity(shape);
            for local in &track.rigid_vertices[b] {
                let p = q.transform_vector(&nalgebra::Vector3::from(*local));
                points.push([
                    r.position[0] + p.x,
                    r.position[1] + p.y,
                    r.position[2] + p.z,
                ]);
                let v = nalgebra::Vector3::from(r.velocity) + w.cross(&p);
                vel.extend_from_slice(&[v.x, v.y, v.z]);
                disp.extend([0, 1, 2].map(|d| r.position[d] - shape.centre[d]));
            }
            for t in &track.rigid_triangles[b] {
                tris.push(t.map(|n| n as usize + offset));
                body.push(rigid_ids[b]);
            }
        }
        let mut grid = Grid::triangles(points, &tris)?;
        grid.add_point_field("displacement_m", 3, disp)?;
        grid.add_point_field("velocity_m_per_s", 3, vel)?;
        grid.add_cell_field("body", 1, body)?;
        self.rigid
            .write_frame(state.time, format!("frames/rigid_{k:04}.vtu"), &grid)?;
        self.frames += 1;
        self.frame_s += started.elapsed().as_secs_f64();
        Ok(())
    }
}

/// Peak resident memory of the process (MiB), from /proc (None elsewhere).
fn peak_memory_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}
