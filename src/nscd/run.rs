//! `ballast-nscd SCENE.toml`: a Moreau–Jean run of an [`NscdScene`] with VTK frames of
//! the grains and of the contact network, a residuals CSV and `summary.json`.
//!
//! Output directory:
//! - `grains.pvd` + `frames/grains_NNNN.vtu`: every dynamic polyhedral body as a
//!   triangulated surface, point field `velocity_m_per_s` (rigid velocity at each
//!   vertex), cell field `id` (body index);
//! - `driven.pvd` + `frames/driven_NNNN.vtu` (when the scene has boxes or driven
//!   meshes): the driven and fixed polyhedral bodies (each convex piece), same fields;
//! - `contacts.pvd` + `frames/contacts_NNNN.vtu`: one line per contact point, from the
//!   first body's mass centre (the contact point for a plane) to the second's, with cell
//!   fields `normal_impulse_N_s`, `tangential_impulse_N_s`, `normal`, `gap_m`;
//! - `residuals.csv`: per step, contacts, warm starts, NLGS sweeps and error, max and
//!   mean interpenetration, the strongest contact's force, kinetic energy, external
//!   work and the energy rise; with a DDM, the interface's contacts and their mean
//!   interpenetration;
//! - `summary.json`: the figures (listed in `docs/nscd.md`).

use std::path::Path;
use std::time::Instant;

use nalgebra::{Point3, Vector3};

use serde::{Deserialize, Serialize};

use super::body::{Body, Motion};
use super::checkpoint::{Checkpoint, CHECKPOINT_FILE};
use super::nlgs::{ErrorCheck, NlgsOptions, Stopping};
use super::scene::{DrivenBody, Model, NscdScene};
use super::step::{MoreauJean, SolvedContact, StepParams};
use crate::ddm::Partitioning;
use crate::output::{write_json, Cadence, CsvSeries, Grid, Progress, PvdWriter, RunClocks};
use crate::pack::contacts::warm_memory;
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::{Error, Result};

/// Runs the scene of `ctx` from the start.
pub fn run(ctx: &RunContext) -> Result<()> {
    run_with(ctx, false, None)
}

/// What a checkpoint keeps of the run loop besides the bodies and the contacts.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct LoopState {
    stats: RunStats,
    slider_samples: Vec<(f64, f64)>,
    slider_mu: Option<f64>,
    pushes: Vec<PushCheck>,
    tamping: Option<super::tamping::TampingState>,
}

/// Runs the scene of `ctx`; with `resume`, from the checkpoint in the output directory
/// (written by a run of the same scene, preset and overrides). With `stop_after`, the
/// run stops once the checkpoint of that step is written (no summary; a later
/// `resume` goes on), unless the run ends first.
pub fn run_with(ctx: &RunContext, resume: bool, stop_after: Option<u64>) -> Result<()> {
    let threads = ctx.configure_threads()?;
    crate::simd::requested_path().map_err(Error::Message)?;
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (NscdScene, _) = timer.time("read scene", || ctx.load_scene())?;
    let scene_text = toml::to_string(&inputs)
        .map_err(|e| Error::Message(format!("cannot write the merged scene: {e}")))?;
    let checkpoint_path = ctx.out_dir.join(CHECKPOINT_FILE);
    let resumed: Option<Checkpoint<LoopState>> = if resume {
        Some(Checkpoint::read(&checkpoint_path, &scene_text)?)
    } else {
        None
    };
    let dt = scene.time.dt.si();
    let steps = (scene.time.duration.si() / dt).round().max(1.0) as u64;
    if let Some(stop) = stop_after {
        if scene.output.checkpoint_every == 0 {
            return Err(Error::Message(format!(
                "{}: --stop-after {stop}: output.checkpoint_every is 0, so a stopped run \
                 could not go on (set it above 0)",
                ctx.scene_path.display()
            )));
        }
        if let Some(c) = &resumed {
            // Stopped there already (a bench that takes turns, whose clocks were lost
            // when the run was killed between writing its checkpoint and its clocks,
            // asks for the same stop again): nothing to do.
            if stop == c.step && stop < steps {
                println!(
                    "ballast-nscd: the checkpoint in {} is at step {stop} already: nothing to \
                     do (--stop-after {stop})",
                    ctx.out_dir.display()
                );
                return Ok(());
            }
            if stop <= c.step {
                return Err(Error::Message(format!(
                    "{}: --stop-after {stop}: the checkpoint is at step {} already",
                    ctx.out_dir.display(),
                    c.step
                )));
            }
        }
    }
    // The bodies after the checks above: a stop with nothing to do, or refused, does
    // not build them (40 000 stones on the tamping7 bed).
    let Model {
        mut bodies,
        friction,
        stone_diameters,
        driven,
        tamping,
        period,
        warm_start,
    } = timer.time("build bodies", || scene.build(&ctx.scene_path))?;
    std::fs::create_dir_all(ctx.out_dir.join("frames")).map_err(|e| Error::io(&ctx.out_dir, e))?;
    if let Some(plan) = &tamping {
        if steps as f64 * dt < plan.end() - 0.5 * dt {
            println!(
                "ballast-nscd: note: the run stops at {:.4} s, before the tamping cycles end \
                 ({:.4} s); compactness_after is the compactness then",
                steps as f64 * dt,
                plan.end()
            );
        }
    }
    let params = StepParams {
        dt,
        theta: scene.time.theta,
        gravity: scene.gravity.vector(),
        alert_distance: scene.solver.alert_distance.si(),
        depenetration_speed: scene.solver.depenetration_speed.map_or(0.0, |v| v.si()),
        period,
        end_checks: scene.solver.end_checks,
    };
    let options = NlgsOptions {
        stopping: match scene.solver.sweeps {
            Some(n) => Stopping::Sweeps(n),
            None => Stopping::Tolerance {
                tolerance: scene.solver.tolerance.unwrap_or(1e-8),
                max_sweeps: scene.solver.max_sweeps,
            },
        },
        error_check: match scene.solver.check_every {
            1 => ErrorCheck::EverySweep,
            every => ErrorCheck::Light { every },
        },
    };
    let mut pipeline = MoreauJean::new(params, options);
    pipeline.set_warm_start(scene.solver.warm_start);
    if let Some(spec) = &scene.ddm {
        // Default partition: two equal slabs along x over the grains' extent.
        let grains: Vec<&Body> = bodies.iter().filter(|b| b.is_dynamic()).collect();
        let (lo, hi) = grains.iter().fold(
            ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
            |(lo, hi), b| {
                (
                    [lo[0].min(b.position.x), lo[1].min(b.position.y)],
                    [hi[0].max(b.position.x), hi[1].max(b.position.y)],
                )
            },
        );
        let extent = if grains.is_empty() {
            [0.0; 4]
        } else {
            [lo[0], hi[0], lo[1], hi[1]]
        };
        // The contacts of the initial configuration, for slabs balanced by count.
        let contacts_x: Vec<f64> = if spec.balanced.is_some() {
            pipeline.detect(&bodies).iter().map(|c| c.point.x).collect()
        } else {
            Vec::new()
        };
        pipeline.ddm = spec.setup(
            extent,
            &contacts_x,
            Partitioning::even_slabs(0, extent[0], extent[1], 2),
        );
    }
    let dynamic = bodies.iter().filter(|b| b.is_dynamic()).count();
    println!(
        "ballast-nscd: {} — {} bodies ({dynamic} dynamic), {steps} steps of {dt:.3e} s, θ = {}, \
         {threads} threads, {} kernel",
        ctx.scene_path.display(),
        bodies.len(),
        params.theta,
        crate::simd::vector_path()
    );

    let has_driven_vtk = bodies
        .iter()
        .any(|b| !b.is_dynamic() && b.shape.collider.is_bounded());
    let mut outputs = Outputs::open(
        &ctx.out_dir,
        has_driven_vtk,
        resumed.as_ref().map(|c| (c.time, c.frames)),
    )?;
    if resumed.is_none() {
        outputs.frame(0.0, &bodies, &[], &[])?;
    }
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
    let mut pushes = if analysis_kind == "push" {
        PushCheck::new(&scene, &driven, &bodies)
    } else {
        Vec::new()
    };
    let driven_start: Vec<Vector3<f64>> = bodies.iter().map(|b| b.position).collect();
    let mut tamping = match tamping {
        Some(plan) => {
            let monitor = timer.time("tamping: compactness", || {
                super::tamping::TampingMonitor::new(plan, &bodies)
            });
            let columns = monitor.columns();
            let names: Vec<&str> = columns.iter().map(String::as_str).collect();
            let path = ctx.out_dir.join("tamping.csv");
            let csv = match &resumed {
                Some(c) => CsvSeries::open_existing(path, &names, c.time)?,
                None => CsvSeries::create(path, &names)?,
            };
            Some((monitor, csv))
        }
        None => None,
    };

    let mut stats = RunStats::default();
    let mut first_step = 1;
    if let (None, Some((contacts, layout))) = (&resumed, &warm_start) {
        let points = pipeline.detect(&bodies);
        let (memory, matched) = warm_memory(&points, contacts, |r| layout.index(r));
        pipeline.set_memory(memory);
        println!(
            "ballast-nscd: warm start: {matched} of {} contact points take the packing's \
             impulses ({} stored)",
            points.len(),
            contacts.len()
        );
    }
    // Wall time of the pieces before this one (a resumed run), from the clocks beside
    // the checkpoint.
    let mut before = RunClocks::default();
    let mut clocks_known = true;
    if let Some(c) = resumed {
        match RunClocks::resume(&ctx.out_dir, c.step, &mut timer) {
            Ok(clocks) => before = clocks,
            Err(note) => {
                clocks_known = false;
                println!("ballast-nscd: {note}");
            }
        }
        pipeline.set_memory(c.restore(&checkpoint_path, &mut bodies)?);
        first_step = c.step + 1;
        let state = c.extra;
        stats = state.stats;
        slider_samples = state.slider_samples;
        slider_mu = state.slider_mu;
        pushes = state.pushes;
        if let (Some((monitor, _)), Some(saved)) = (&mut tamping, state.tamping) {
            monitor.state = saved;
        }
        println!(
            "ballast-nscd: resumed from {} at step {} (t = {:.4} s)",
            checkpoint_path.display(),
            c.step,
            c.time
        );
    }
    let mut bar = Progress::steps(steps, "ballast-nscd");
    let start = Instant::now();
    let mut frames_s = 0.0;
    let mut cadence = Cadence::new(
        scene.output.checkpoint_every,
        scene.output.checkpoint_wall_every,
    );
    let mut time = (first_step - 1) as f64 * dt;
    bar.set_position(first_step - 1);
    for step in first_step..=steps {
        if let Some((monitor, _)) = &mut tamping {
            monitor.actuate(time, dt, &mut bodies);
        }
        let report = pipeline.step(&mut bodies, time, &friction);
        time = step as f64 * dt;
        for (k, name) in ["detect", "build", "solve", "update"].iter().enumerate() {
            timer.add(name, report.phase_times[k]);
        }
        if pipeline.ddm.is_some() {
            timer.add("solve: subdomains (parallel)", report.solve_split[0]);
            timer.add("solve: interface (sequential)", report.solve_split[1]);
            let subdomains = pipeline.decomposition().subdomains.len();
            for (k, busy) in pipeline.block_busy().iter().enumerate() {
                let name = if k < subdomains {
                    format!("solve: subdomain {} sweeps", k + 1)
                } else {
                    "solve: interface block sweeps".to_string()
                };
                timer.add(&name, *busy);
            }
        }
        stats.record(&report, &bodies, &initial);
        stats.record_deepest(time, pipeline.contacts());
        outputs.residuals.push(&[
            time,
            report.contacts as f64,
            report.warm_started as f64,
            report.nlgs.iterations as f64,
            report.nlgs.error,
            report.max_interpenetration,
            report.mean_interpenetration,
            report.max_contact_force,
            report.kinetic_energy,
            report.external_work,
            report.energy_rise,
            report.interface_contacts as f64,
            report.interface_mean_interpenetration,
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
        if let Some((monitor, csv)) = &mut tamping {
            let clock = Instant::now();
            let sample = step % monitor.plan.sample_every == 0 || step == steps;
            let row = monitor.record(time, sample, &bodies, pipeline.contacts(), dt);
            csv.push(&row)?;
            timer.add("tamping: compactness", clock.elapsed());
        }
        for push in &mut pushes {
            push.record(
                time,
                time >= fit_after,
                &bodies,
                pipeline.contacts(),
                &friction,
            );
        }
        if step % frame_every == 0 || step == steps {
            let clock = Instant::now();
            outputs.frame(time, &bodies, pipeline.contacts(), pipeline.subdomains())?;
            frames_s += clock.elapsed().as_secs_f64();
            bar.set_position(step);
        }
        let every = scene.output.checkpoint_every;
        let stop_here = stop_after == Some(step) && step < steps;
        if cadence.due(step) || (every > 0 && (step == steps || stop_here)) {
            let clock = Instant::now();
            let state = LoopState {
                stats: stats.clone(),
                slider_samples: slider_samples.clone(),
                slider_mu,
                pushes: pushes.clone(),
                tamping: tamping.as_ref().map(|(m, _)| m.state.clone()),
            };
            Checkpoint::capture(
                scene_text.clone(),
                step,
                time,
                outputs.frames,
                &bodies,
                pipeline.memory(),
                state,
            )
            .write(&checkpoint_path)?;
            cadence.written();
            timer.add("checkpoints", clock.elapsed());
            let stepping = start.elapsed().as_secs_f64() - frames_s;
            before
                .then(step, stepping, frames_s, &timer)
                .write(&ctx.out_dir)?;
            if stop_here {
                bar.finish_and_clear();
                println!(
                    "ballast-nscd: stopped after step {step} of {steps} (t = {time:.4} s), \
                     checkpoint written; --resume {} goes on",
                    ctx.out_dir.display()
                );
                return Ok(());
            }
        }
        if !report.kinetic_energy.is_finite() {
            bar.abandon();
            return Err(Error::Message(format!(
                "ballast-nscd: the kinetic energy is not finite at t = {time:.4e} s (step {step})"
            )));
        }
    }
    bar.finish_and_clear();
    let stepping_s = before.stepping_s + start.elapsed().as_secs_f64() - frames_s;
    let frames_s = before.frames_s + frames_s;
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
        .figure("kernel", crate::simd::vector_path())
        .figure(
            "contact_updates_per_s",
            stats.sweeps_contacts as f64 / timer.get("solve").as_secs_f64().max(1e-12),
        )
        .figure("stepping_s", stepping_s)
        .figure("pieces", before.pieces + 1)
        .figure("wall_times_complete", clocks_known);
    if let Some((depth, at, a, b)) = stats.deepest {
        summary = summary.figure(
            "deepest_overlap",
            serde_json::json!({
                "depth_m": depth,
                "step_end_s": at,
                "bodies": [bodies[a as usize].name, bodies[b as usize].name],
            }),
        );
    }
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
    // Driven bodies: the position reached against the exact integral of the prescribed
    // velocity (exact for θ = 0.5 and a piecewise-linear velocity with its breakpoints
    // on step boundaries; O(h²) per unit time otherwise).
    let mut driven_error: Option<f64> = None;
    // The tines' squeeze follows the ballast's push (TampingMonitor::actuate): not
    // prescribed in advance, so not checked here.
    let actuated: Vec<usize> = tamping.as_ref().map_or(Vec::new(), |(m, _)| {
        m.plan.tines.iter().flat_map(|t| t.pieces.clone()).collect()
    });
    for (k, body) in bodies.iter().enumerate() {
        if actuated.contains(&k) {
            continue;
        }
        if let Motion::Driven(prescribed) = &body.motion {
            let expected = driven_start[k] + prescribed.displacement(0.0, time);
            let error = (body.position - expected).norm();
            driven_error = Some(driven_error.unwrap_or(0.0).max(error));
        }
    }
    if let Some(error) = driven_error {
        summary = summary.figure("driven_max_position_error_m", error);
    }
    if !pushes.is_empty() {
        let mut worst_impulse: f64 = 0.0;
        let mut worst_velocity: f64 = 0.0;
        for push in &pushes {
            let (impulse, velocity) = push.errors();
            worst_impulse = worst_impulse.max(impulse);
            worst_velocity = worst_velocity.max(velocity);
            let tag = format!("push_{}", push.pushed_name);
            summary = summary
                .figure(&format!("{tag}_mu"), push.mu.unwrap_or(f64::NAN))
                .figure(&format!("{tag}_mass_kg"), push.mass)
                .figure(
                    &format!("{tag}_impulse_expected_N_s"),
                    push.expected().unwrap_or(f64::NAN),
                )
                .figure(&format!("{tag}_mean_impulse_N_s"), push.mean_impulse())
                .figure(&format!("{tag}_impulse_relative_error"), impulse)
                .figure(&format!("{tag}_velocity_relative_error"), velocity)
                .figure(&format!("{tag}_samples"), push.samples);
        }
        summary = summary
            .figure("push_max_impulse_relative_error", worst_impulse)
            .figure("push_max_velocity_relative_error", worst_velocity);
    }
    if let Some((monitor, _)) = &tamping {
        summary = monitor.figures(summary);
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

/// One pusher–block pair of a `push` analysis: the impulse the pusher's pieces give the
/// block per step (along the pusher's velocity) against Coulomb's µ m g h of the floor,
/// and the block's velocity against the pusher's.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct PushCheck {
    pieces: Vec<usize>,
    pushed: usize,
    pushed_name: String,
    mass: f64,
    gravity: f64,
    dt: f64,
    /// µ between the block and the fixed body it slides on (found from the contacts).
    mu: Option<f64>,
    samples: usize,
    impulse_sum: f64,
    impulses: Vec<f64>,
    max_velocity_error: f64,
}

impl PushCheck {
    fn new(scene: &NscdScene, driven: &[DrivenBody], bodies: &[Body]) -> Vec<PushCheck> {
        let Some(a) = &scene.analysis else {
            return Vec::new();
        };
        let pushers = a.pushers.as_deref().unwrap_or(&[]);
        let pushed = a.pushed.as_deref().unwrap_or(&[]);
        pushers
            .iter()
            .zip(pushed)
            .filter_map(|(p, q)| {
                let pieces = driven.iter().find(|d| &d.name == p)?.pieces.clone();
                let pushed = bodies.iter().position(|b| &b.name == q)?;
                Some(PushCheck {
                    pieces,
                    pushed,
                    pushed_name: q.clone(),
                    mass: bodies[pushed].mass,
                    gravity: scene.gravity.vector().norm(),
                    dt: scene.time.dt.si(),
                    mu: None,
                    samples: 0,
                    impulse_sum: 0.0,
                    impulses: Vec::new(),
                    max_velocity_error: 0.0,
                })
            })
            .collect()
    }

    fn record(
        &mut self,
        _time: f64,
        measure: bool,
        bodies: &[Body],
        contacts: &[SolvedContact],
        friction: &super::step::FrictionTable,
    ) {
        let mut impulse = Vector3::zeros();
        for c in contacts {
            let (a, b) = (c.contact.key.body_a as usize, c.contact.key.body_b as usize);
            let world = c.world_impulse();
            if b == self.pushed && self.pieces.contains(&a) {
                impulse += world;
            } else if a == self.pushed && self.pieces.contains(&b) {
                impulse -= world;
            }
            if self.mu.is_none() && (a == self.pushed || b == self.pushed) {
                let other = if a == self.pushed { b } else { a };
                if matches!(bodies[other].motion, Motion::Static) {
                    self.mu = Some(friction.get(bodies[a].material, bodies[b].material));
                }
            }
        }
        if !measure {
            return;
        }
        let v_pusher = bodies[self.pieces[0]].velocity;
        let speed = v_pusher.norm();
        if speed == 0.0 {
            return;
        }
        let along = impulse.dot(&v_pusher) / speed;
        self.samples += 1;
        self.impulse_sum += along;
        self.impulses.push(along);
        let error = (bodies[self.pushed].velocity - v_pusher).norm() / speed;
        self.max_velocity_error = self.max_velocity_error.max(error);
    }

    /// µ m g h.
    fn expected(&self) -> Option<f64> {
        self.mu.map(|mu| mu * self.mass * self.gravity * self.dt)
    }

    fn mean_impulse(&self) -> f64 {
        if self.samples == 0 {
            f64::NAN
        } else {
            self.impulse_sum / self.samples as f64
        }
    }

    /// Largest relative error of the impulse per step and of the block's velocity over
    /// the measured steps (NaN without samples).
    fn errors(&self) -> (f64, f64) {
        match (self.expected(), self.samples) {
            (Some(expected), n) if n > 0 => (
                self.impulses
                    .iter()
                    .map(|p| (p - expected).abs() / expected.abs())
                    .fold(0.0, f64::max),
                self.max_velocity_error,
            ),
            _ => (f64::NAN, f64::NAN),
        }
    }
}

/// Running figures of a run.
#[derive(Debug, Default, Clone, Serialize, Deserialize)]
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
    /// The deepest overlap at the start of a step: depth (m), time (s), the two bodies.
    deepest: Option<(f64, f64, u32, u32)>,
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

    /// Keeps the deepest of `contacts` (a step's, detected at its start) if it is the
    /// deepest so far.
    fn record_deepest(&mut self, time: f64, contacts: &[SolvedContact]) {
        if let Some(c) = contacts
            .iter()
            .min_by(|a, b| a.contact.gap.total_cmp(&b.contact.gap))
        {
            let depth = -c.contact.gap;
            if depth > 0.0 && self.deepest.is_none_or(|(d, ..)| depth > d) {
                let key = c.contact.key;
                self.deepest = Some((depth, time, key.body_a, key.body_b));
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
    driven: Option<PvdWriter>,
    contacts: PvdWriter,
    residuals: CsvSeries,
    frames: usize,
}

impl Outputs {
    /// New files, or (`resume`: the checkpoint's time and frame count) the files of
    /// the killed run cut back to the checkpoint.
    fn open(dir: &Path, driven: bool, resume: Option<(f64, usize)>) -> Result<Self> {
        let pvd = |name: &str| match resume {
            Some((time, _)) => PvdWriter::open_existing(dir.join(name), time),
            None => PvdWriter::create(dir.join(name)),
        };
        let csv = |name: &str, columns: &[&str]| match resume {
            Some((time, _)) => CsvSeries::open_existing(dir.join(name), columns, time),
            None => CsvSeries::create(dir.join(name), columns),
        };
        Ok(Outputs {
            grains: pvd("grains.pvd")?,
            driven: if driven {
                Some(pvd("driven.pvd")?)
            } else {
                None
            },
            contacts: pvd("contacts.pvd")?,
            residuals: csv(
                "residuals.csv",
                &[
                    "time_s",
                    "contacts",
                    "warm_started",
                    "nlgs_sweeps",
                    "nlgs_error",
                    "max_interpenetration_m",
                    "mean_interpenetration_m",
                    "max_contact_force_N",
                    "kinetic_energy_J",
                    "external_work_J",
                    "energy_rise_J",
                    "interface_contacts",
                    "interface_mean_interpenetration_m",
                ],
            )?,
            frames: resume.map_or(0, |(_, frames)| frames),
        })
    }

    fn frame(
        &mut self,
        time: f64,
        bodies: &[Body],
        contacts: &[SolvedContact],
        subdomains: &[Option<u32>],
    ) -> Result<()> {
        let name = format!("frames/grains_{:04}.vtu", self.frames);
        self.grains.write_frame(
            time,
            &name,
            &grains_grid(bodies, Drawn::Moving, subdomains)?,
        )?;
        if let Some(driven) = &mut self.driven {
            let name = format!("frames/driven_{:04}.vtu", self.frames);
            driven.write_frame(time, &name, &grains_grid(bodies, Drawn::Fixed, &[])?)?;
        }
        let name = format!("frames/contacts_{:04}.vtu", self.frames);
        self.contacts
            .write_frame(time, &name, &contacts_grid(bodies, contacts)?)?;
        self.frames += 1;
        Ok(())
    }
}

/// Which polyhedral bodies [`grains_grid`] draws.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drawn {
    /// The dynamic ones (grains).
    Moving,
    /// The driven and fixed ones (tools, sleepers, walls).
    Fixed,
    /// All of them (a packing's sleepers, free or held).
    All,
}

/// Polyhedral bodies as triangulated surfaces (those `drawn` says), with each body's
/// `id` and DDM `subdomain` (from `subdomains`, one entry per body; −1 for none or an
/// empty slice).
pub fn grains_grid(bodies: &[Body], drawn: Drawn, subdomains: &[Option<u32>]) -> Result<Grid> {
    let mut points = Vec::new();
    let mut triangles = Vec::new();
    let mut velocity = Vec::new();
    let mut ids = Vec::new();
    let mut domains = Vec::new();
    for (k, body) in bodies.iter().enumerate() {
        let wanted = match drawn {
            Drawn::Moving => body.is_dynamic(),
            Drawn::Fixed => !body.is_dynamic(),
            Drawn::All => true,
        };
        if !body.shape.collider.is_bounded() || !wanted {
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
            domains.push(
                subdomains
                    .get(k)
                    .copied()
                    .flatten()
                    .map_or(-1, |d| d as i32),
            );
        }
    }
    let mut grid = Grid::triangles(points, &triangles)?;
    grid.add_point_field("velocity_m_per_s", 3, velocity)?;
    grid.add_cell_field("id", 1, ids)?;
    grid.add_cell_field("subdomain", 1, domains)?;
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
        // Across a periodic end: to the image the contact touches.
        let end = bodies[b].position + c.contact.shift_b;
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
