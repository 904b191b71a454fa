//! `ballast-nscd SCENE.toml`: a Moreau–Jean run of an [`NscdScene`] with VTK frames of
//! the grains and of the contact network, a residuals CSV and `summary.json`.
//!
//! Output directory:
//! - `grains.pvd` + `frames/grains_NNNN.vtu`: every polyhedral body as a triangulated
//!   surface, point field `velocity_m_per_s` (rigid velocity at each vertex), cell field
//!   `id` (body index);
//! - `contacts.pvd` + `frames/contacts_NNNN.vtu`: one line per contact point, from the
//!   first body's mass centre (the contact point for a plane) to the second's, with cell
//!   fields `normal_impulse_N_s`, `tangential_impulse_N_s`, `normal`, `gap_m`;
//! - `residuals.csv`: per step, contacts, warm starts, NLGS sweeps and error, max and
//!   mean interpenetration, kinetic energy, external work and the energy rise;
//! - `summary.json`: the figures (listed in `docs/nscd.md`).

use std::path::Path;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use nalgebra::{Point3, Vector3};

use super::body::{Body, Motion};
use super::nlgs::{ErrorCheck, NlgsOptions, Stopping};
use super::scene::{Model, NscdScene};
use super::step::{MoreauJean, SolvedContact, StepParams};
use crate::contact::Collider;
use crate::output::{write_json, CsvSeries, Grid, PvdWriter};
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::{Error, Result};

/// Runs the scene of `ctx`.
pub fn run(ctx: &RunContext) -> Result<()> {
    let threads = ctx.configure_threads()?;
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (NscdScene, _) = timer.time("read scene", || ctx.load_scene())?;
    let Model {
        mut bodies,
        friction,
        stone_diameters,
    } = timer.time("build bodies", || scene.build(&ctx.scene_path))?;
    std::fs::create_dir_all(ctx.out_dir.join("frames")).map_err(|e| Error::io(&ctx.out_dir, e))?;
    let dt = scene.time.dt.si();
    let steps = (scene.time.duration.si() / dt).round().max(1.0) as u64;
    let params = StepParams {
        dt,
        theta: scene.time.theta,
        gravity: scene.gravity.vector(),
        alert_distance: scene.solver.alert_distance.si(),
    };
    let options = NlgsOptions {
        stopping: match scene.solver.sweeps {
            Some(n) => Stopping::Sweeps(n),
            None => Stopping::Tolerance {
                tolerance: scene.solver.tolerance.unwrap_or(1e-8),
                max_sweeps: scene.solver.max_sweeps,
            },
        },
        error_check: ErrorCheck::EverySweep,
    };
    let mut pipeline = MoreauJean::new(params, options);
    let dynamic = bodies.iter().filter(|b| b.is_dynamic()).count();
    println!(
        "ballast-nscd: {} — {} bodies ({dynamic} dynamic), {steps} steps of {dt:.3e} s, θ = {}, \
         {threads} threads",
        ctx.scene_path.display(),
        bodies.len(),
        params.theta
    );

    let mut outputs = Outputs::create(&ctx.out_dir)?;
    outputs.frame(0.0, &bodies, &[])?;
    let frame_every = if scene.output.frames == 0 {
        u64::MAX
    } else {
        (steps / scene.output.frames as u64).max(1)
    };
    let initial: Vec<Vec<Point3<f64>>> = bodies.iter().map(Body::world_vertices).collect();
    let analysis_kind = scene
        .analysis
        .as_ref()
        .map(|a| a.kind.as_str())
        .unwrap_or("");
    let find = |name: &Option<String>| {
        name.as_ref()
            .and_then(|n| bodies.iter().position(|b| &b.name == n))
    };
    let slider = scene.analysis.as_ref().and_then(|a| find(&a.slider));
    let sticker = scene.analysis.as_ref().and_then(|a| find(&a.sticker));
    let fit_after = scene
        .analysis
        .as_ref()
        .and_then(|a| a.after)
        .map_or(0.0, |t| t.si());
    let mut slider_samples: Vec<(f64, f64)> = Vec::new();
    let mut slider_mu = None;

    let mut stats = RunStats::default();
    let bar = ProgressBar::with_draw_target(Some(steps), ProgressDrawTarget::stderr_with_hz(4));
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps, {per_sec}, eta {eta}")
            .expect("valid template"),
    );
    let start = Instant::now();
    let mut frames_s = 0.0;
    let mut time = 0.0;
    for step in 1..=steps {
        let report = pipeline.step(&mut bodies, time, &friction);
        time = step as f64 * dt;
        for (k, name) in ["detect", "build", "solve", "update"].iter().enumerate() {
            timer.add(name, report.phase_times[k]);
        }
        stats.record(&report, &bodies, &initial);
        outputs.residuals.push(&[
            time,
            report.contacts as f64,
            report.warm_started as f64,
            report.nlgs.iterations as f64,
            report.nlgs.error,
            report.max_interpenetration,
            report.mean_interpenetration,
            report.kinetic_energy,
            report.external_work,
            report.energy_rise,
        ])?;
        if let Some(s) = slider {
            if time >= fit_after {
                slider_samples.push((time, bodies[s].velocity.x));
            }
            if slider_mu.is_none() {
                slider_mu = pipeline.contacts().iter().find_map(|c| {
                    let (a, b) = (c.contact.key.body_a as usize, c.contact.key.body_b as usize);
                    (a == s || b == s).then(|| friction.get(bodies[a].material, bodies[b].material))
                });
            }
        }
        if step % frame_every == 0 || step == steps {
            let clock = Instant::now();
            outputs.frame(time, &bodies, pipeline.contacts())?;
            frames_s += clock.elapsed().as_secs_f64();
            bar.set_position(step);
        }
        if !report.kinetic_energy.is_finite() {
            bar.abandon();
            return Err(Error::Message(format!(
                "ballast-nscd: the kinetic energy is not finite at t = {time:.4e} s (step {step})"
            )));
        }
    }
    bar.finish_and_clear();
    let stepping_s = start.elapsed().as_secs_f64() - frames_s;
    timer.add("vtk frames", std::time::Duration::from_secs_f64(frames_s));

    // The final configuration's interpenetration (not just the last step's start).
    let final_contacts = timer.time("final detection", || pipeline.detect(&bodies));
    let penetrations: Vec<f64> = final_contacts
        .iter()
        .filter(|c| c.gap < 0.0)
        .map(|c| -c.gap)
        .collect();
    let final_max = penetrations.iter().copied().fold(0.0, f64::max);
    let final_mean = if penetrations.is_empty() {
        0.0
    } else {
        penetrations.iter().sum::<f64>() / penetrations.len() as f64
    };
    let touching = final_contacts.iter().filter(|c| c.gap <= 0.0).count();

    let mut summary = Summary::new(ctx, &inputs)
        .figure("bodies", bodies.len())
        .figure("dynamic_bodies", dynamic)
        .figure("steps", steps)
        .figure("dt_s", dt)
        .figure("theta", params.theta)
        .figure("mean_contacts", stats.contacts_sum as f64 / steps as f64)
        .figure("mean_sweeps", stats.sweeps_sum as f64 / steps as f64)
        .figure("max_sweeps", stats.max_sweeps)
        .figure("unconverged_steps", stats.unconverged)
        .figure("max_nlgs_error", stats.max_error)
        .figure("max_drift_m", stats.max_drift)
        .figure("max_interpenetration_m", stats.max_pen)
        .figure("max_mean_interpenetration_m", stats.max_mean_pen)
        .figure("final_max_interpenetration_m", final_max)
        .figure("final_mean_interpenetration_m", final_mean)
        .figure("final_touching_contacts", touching)
        .figure("final_kinetic_energy_J", stats.last_kinetic)
        .figure("max_kinetic_energy_J", stats.max_kinetic)
        .figure("total_external_work_J", stats.work_sum)
        .figure("max_energy_rise_J", stats.max_rise)
        .figure(
            "max_energy_rise_relative",
            if stats.work_sum.abs() > 0.0 {
                stats.max_rise / stats.work_sum.abs()
            } else {
                stats.max_rise
            },
        )
        .figure(
            "contact_updates_per_s",
            stats.sweeps_contacts as f64 / timer.get("solve").as_secs_f64().max(1e-12),
        )
        .figure("stepping_s", stepping_s);
    if !stone_diameters.is_empty() {
        let mut sorted = stone_diameters.clone();
        sorted.sort_by(f64::total_cmp);
        let d50 = sorted[sorted.len() / 2];
        summary = summary
            .figure("d50_m", d50)
            .figure("final_mean_interpenetration_over_d50", final_mean / d50)
            .figure("final_max_interpenetration_over_d50", final_max / d50);
    }
    if analysis_kind == "incline" {
        if let (Some(_), Some(k)) = (slider, sticker) {
            let g = scene.gravity.magnitude.si();
            let alpha = scene.gravity.incline.map_or(0.0, |a| a.si());
            let mu = slider_mu.unwrap_or(f64::NAN);
            let expected = g * (alpha.sin() - mu * alpha.cos());
            let measured = slope(&slider_samples);
            let sticker_slip = (bodies[k].position - initial_centre(&initial[k])).norm();
            summary = summary
                .figure("incline_deg", alpha.to_degrees())
                .figure("slider_mu", mu)
                .figure("slide_acceleration_m_per_s2", measured)
                .figure("slide_acceleration_expected_m_per_s2", expected)
                .figure(
                    "slide_acceleration_relative_error",
                    (measured - expected).abs() / expected.abs(),
                )
                .figure("sticker_displacement_m", sticker_slip)
                .figure("sticker_max_speed_m_per_s", stats.speed_of(k));
        }
    }
    let summary = summary.wall_times(&timer);
    write_json(ctx.out_dir.join("summary.json"), &summary.to_json())?;
    println!(
        "ballast-nscd: {steps} steps in {stepping_s:.2} s; mean {:.1} contacts, {:.1} sweeps; \
         max interpenetration {:.3e} m, final mean {:.3e} m; max energy rise {:.3e} J",
        stats.contacts_sum as f64 / steps as f64,
        stats.sweeps_sum as f64 / steps as f64,
        stats.max_pen,
        final_mean,
        stats.max_rise
    );
    println!(
        "ballast-nscd: wrote {}",
        ctx.out_dir.join("summary.json").display()
    );
    Ok(())
}

fn initial_centre(vertices: &[Point3<f64>]) -> Vector3<f64> {
    if vertices.is_empty() {
        return Vector3::zeros();
    }
    vertices.iter().map(|p| p.coords).sum::<Vector3<f64>>() / vertices.len() as f64
}

/// Least-squares slope of (t, v) samples.
fn slope(samples: &[(f64, f64)]) -> f64 {
    let n = samples.len() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let (mt, mv) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, v)| (a + t / n, b + v / n));
    let (mut stv, mut stt) = (0.0, 0.0);
    for (t, v) in samples {
        stv += (t - mt) * (v - mv);
        stt += (t - mt) * (t - mt);
    }
    stv / stt
}

/// Running figures of a run.
#[derive(Debug, Default)]
struct RunStats {
    contacts_sum: u64,
    sweeps_sum: u64,
    sweeps_contacts: u64,
    max_sweeps: usize,
    unconverged: u64,
    max_error: f64,
    max_drift: f64,
    max_pen: f64,
    max_mean_pen: f64,
    max_rise: f64,
    steps: u64,
    work_sum: f64,
    max_kinetic: f64,
    last_kinetic: f64,
    max_speed: Vec<f64>,
}

impl RunStats {
    fn record(
        &mut self,
        report: &super::step::StepReport,
        bodies: &[Body],
        initial: &[Vec<Point3<f64>>],
    ) {
        self.contacts_sum += report.contacts as u64;
        self.sweeps_sum += report.nlgs.iterations as u64;
        self.sweeps_contacts += (report.nlgs.iterations * report.contacts) as u64;
        self.max_sweeps = self.max_sweeps.max(report.nlgs.iterations);
        if !report.nlgs.converged {
            self.unconverged += 1;
        }
        self.max_error = self.max_error.max(report.nlgs.error);
        self.max_pen = self.max_pen.max(report.max_interpenetration);
        self.max_mean_pen = self.max_mean_pen.max(report.mean_interpenetration);
        // The largest per-step ΔKE − W, negative when every step dissipated.
        self.max_rise = if self.steps == 0 {
            report.energy_rise
        } else {
            self.max_rise.max(report.energy_rise)
        };
        self.steps += 1;
        self.work_sum += report.external_work;
        self.max_kinetic = self.max_kinetic.max(report.kinetic_energy);
        self.last_kinetic = report.kinetic_energy;
        if self.max_speed.len() != bodies.len() {
            self.max_speed = vec![0.0; bodies.len()];
        }
        for (k, body) in bodies.iter().enumerate() {
            if !body.is_dynamic() {
                continue;
            }
            self.max_speed[k] = self.max_speed[k].max(body.velocity.norm());
            let pose = body.pose();
            for (p, p0) in body.shape.vertices.iter().zip(&initial[k]) {
                self.max_drift = self.max_drift.max((pose * p - p0).norm());
            }
        }
    }

    fn speed_of(&self, k: usize) -> f64 {
        self.max_speed.get(k).copied().unwrap_or(0.0)
    }
}

/// The run's files.
struct Outputs {
    grains: PvdWriter,
    contacts: PvdWriter,
    residuals: CsvSeries,
    frames: usize,
}

impl Outputs {
    fn create(dir: &Path) -> Result<Self> {
        Ok(Outputs {
            grains: PvdWriter::create(dir.join("grains.pvd"))?,
            contacts: PvdWriter::create(dir.join("contacts.pvd"))?,
            residuals: CsvSeries::create(
                dir.join("residuals.csv"),
                &[
                    "time_s",
                    "contacts",
                    "warm_started",
                    "nlgs_sweeps",
                    "nlgs_error",
                    "max_interpenetration_m",
                    "mean_interpenetration_m",
                    "kinetic_energy_J",
                    "external_work_J",
                    "energy_rise_J",
                ],
            )?,
            frames: 0,
        })
    }

    fn frame(&mut self, time: f64, bodies: &[Body], contacts: &[SolvedContact]) -> Result<()> {
        let name = format!("frames/grains_{:04}.vtu", self.frames);
        self.grains
            .write_frame(time, &name, &grains_grid(bodies)?)?;
        let name = format!("frames/contacts_{:04}.vtu", self.frames);
        self.contacts
            .write_frame(time, &name, &contacts_grid(bodies, contacts)?)?;
        self.frames += 1;
        Ok(())
    }
}

/// Polyhedral bodies as triangulated surfaces.
pub fn grains_grid(bodies: &[Body]) -> Result<Grid> {
    let mut points = Vec::new();
    let mut triangles = Vec::new();
    let mut velocity = Vec::new();
    let mut ids = Vec::new();
    for (k, body) in bodies.iter().enumerate() {
        if !matches!(body.shape.collider, Collider::Convex(_)) {
            continue;
        }
        let base = points.len();
        let pose = body.pose();
        let omega = body.angular_velocity_world();
        for p in &body.shape.vertices {
            let q = pose * p;
            let v = body.velocity + omega.cross(&(q.coords - body.position));
            points.push([q.x, q.y, q.z]);
            velocity.extend_from_slice(&[v.x, v.y, v.z]);
        }
        for t in &body.shape.triangles {
            triangles.push(t.map(|i| base + i as usize));
            ids.push(k as i32);
        }
    }
    let mut grid = Grid::triangles(points, &triangles)?;
    grid.add_point_field("velocity_m_per_s", 3, velocity)?;
    grid.add_cell_field("id", 1, ids)?;
    Ok(grid)
}

/// The contact network as lines between mass centres (from the contact point for a
/// half-space), with the impulses.
pub fn contacts_grid(bodies: &[Body], contacts: &[SolvedContact]) -> Result<Grid> {
    let mut points = Vec::with_capacity(2 * contacts.len());
    let mut lines = Vec::with_capacity(contacts.len());
    let (mut normal_impulse, mut tangential_impulse, mut normals, mut gaps) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for c in contacts {
        let (a, b) = (c.contact.key.body_a as usize, c.contact.key.body_b as usize);
        let start = if matches!(bodies[a].motion, Motion::Dynamic) {
            bodies[a].position
        } else {
            c.contact.point.coords
        };
        let end = bodies[b].position;
        lines.push([points.len(), points.len() + 1]);
        points.push([start.x, start.y, start.z]);
        points.push([end.x, end.y, end.z]);
        normal_impulse.push(c.impulse[0]);
        tangential_impulse.push(c.impulse[1].hypot(c.impulse[2]));
        normals.extend_from_slice(&[c.frame[0].x, c.frame[0].y, c.frame[0].z]);
        gaps.push(c.contact.gap);
    }
    let mut grid = Grid::lines(points, &lines)?;
    grid.add_cell_field("normal_impulse_N_s", 1, normal_impulse)?;
    grid.add_cell_field("tangential_impulse_N_s", 1, tangential_impulse)?;
    grid.add_cell_field("normal", 3, normals)?;
    grid.add_cell_field("gap_m", 1, gaps)?;
    Ok(grid)
}
