//! `ballast-qdem SCENE.toml`: one explicit QDEM run per case of a [`SolidScene`], with
//! the stable time step printed first, a progress bar, VTK frames, probe and energy
//! CSV series, and the scene's headline figure in `summary.json`.
//!
//! Layout of the output directory (one sub-directory per `[[case]]` when there are
//! cases):
//! - `mesh.pvd` + `frames/mesh_NNNN.vtu`: reference mesh with point fields
//!   `displacement_m`, `velocity_m_per_s` and cell fields `stress_Pa` (9 components,
//!   Cauchy T = T_E + T_D of eq. 8) and `von_mises_Pa`;
//! - `probes.csv`: `time_s`, then `<probe>_ux_m`, `<probe>_uy_m`, `<probe>_uz_m`;
//! - `energies.csv`: kinetic, strain, viscous and numerical dissipation, external work,
//!   and the balance error (J);
//! - `summary.json` (top level): stable and used time steps, steps, throughput,
//!   the analysis figures and the wall time per phase.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde_json::{json, Value};

use super::analysis::{analyse, ProbeSeries};
use super::scene::{DampingSpec, QdemSpec, SolidScene, TimeStep};
use super::setup::{boundary, case_material, probes, Probe};
use crate::mesh::{read_msh, TetMesh};
use crate::output::{write_json, CsvSeries, Grid, Progress, PvdWriter};
use crate::qdem::{
    stability, von_mises, Damping, QdemModel, QdemOptions, QdemSolver, StableTimeStep, State,
};
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::{Error, Result};

/// What one case produced, for the analysis and the summary.
#[derive(Debug)]
pub struct CaseRun {
    /// Case name ("" for a scene without cases).
    pub name: String,
    /// Where the case's files are.
    pub dir: PathBuf,
    /// The material used.
    pub material: crate::qdem::QdemMaterial,
    /// Stable step analysis.
    pub stable: StableTimeStep,
    /// Step used (s).
    pub dt: f64,
    /// Steps taken.
    pub steps: u64,
    /// Probe time series.
    pub probes: Vec<ProbeSeries>,
    /// Final energies (J): kinetic, strain, balance error.
    pub final_energies: Value,
    /// Wall time of the stepping loop (s).
    pub stepping_s: f64,
    /// Tetra updates per second in the stepping loop (probe sampling included, VTK
    /// frames not).
    pub tetra_updates_per_s: f64,
}

/// Runs every case of the scene and writes the summary.
pub fn run(ctx: &RunContext, force: bool) -> Result<()> {
    let threads = ctx.configure_threads()?;
    crate::simd::requested_path().map_err(Error::Message)?;
    let mut timer = PhaseTimer::new();
    let (scene, inputs): (SolidScene, _) = timer.time("read scene", || ctx.load_scene())?;
    let spec = scene.qdem.clone().ok_or_else(|| {
        Error::invalid(
            &ctx.scene_path,
            "no [qdem] section: ballast-qdem needs duration and dt there",
        )
    })?;
    let mesh_path = SolidScene::resolve(&ctx.scene_path, &scene.mesh.file);
    // Renumbered for locality: the kernel gathers and scatters per tetra.
    let mesh = timer.time("read mesh", || {
        read_msh(&mesh_path).map(TetMesh::locality_ordered)
    })?;
    std::fs::create_dir_all(&ctx.out_dir).map_err(|e| Error::io(&ctx.out_dir, e))?;
    say(format_args!(
        "ballast-qdem: {} — {} nodes, {} tetra, {threads} threads, {} kernel",
        mesh_path.display(),
        mesh.nodes.len(),
        mesh.tets.len(),
        crate::simd::vector_path()
    ));
    let mut runs = Vec::new();
    for case in scene.cases() {
        let dir = if case.name.is_empty() {
            ctx.out_dir.clone()
        } else {
            ctx.out_dir.join(&case.name)
        };
        let run = run_case(ctx, &scene, &spec, &mesh, &case, &dir, force, &mut timer)?;
        runs.push(run);
    }
    let figures = timer.time("analysis", || {
        analyse(&ctx.scene_path, &scene, &mesh, &runs)
    })?;
    let mut summary = Summary::new(ctx, &inputs)
        .figure("nodes", mesh.nodes.len())
        .figure("tetra", mesh.tets.len())
        .figure("volume_m3", mesh.total_volume())
        .figure("stable_dt_s", runs[0].stable.stable)
        .figure("dt_s", runs[0].dt)
        .figure("steps", runs[0].steps)
        .figure("kernel", crate::simd::vector_path())
        .figure(
            "tetra_updates_per_s",
            runs.iter().map(|r| r.tetra_updates_per_s).sum::<f64>() / runs.len() as f64,
        );
    if !scene.case.is_empty() {
        summary = summary.figure("cases", runs.iter().map(case_json).collect::<Vec<_>>());
    } else {
        summary = summary.figure("final_energies_J", runs[0].final_energies.clone());
    }
    for (name, value) in figures {
        summary = summary.figure(&name, value);
    }
    let summary = summary.wall_times(&timer);
    write_json(ctx.out_dir.join("summary.json"), &summary.to_json())?;
    say(format_args!(
        "ballast-qdem: wrote {}",
        ctx.out_dir.join("summary.json").display()
    ));
    Ok(())
}

/// A line of the run's report on stdout; a closed stdout (`| head`) is not an error.
pub(crate) fn say(line: std::fmt::Arguments) {
    use std::io::Write as _;
    let _ = writeln!(std::io::stdout().lock(), "{line}");
}

fn case_json(run: &CaseRun) -> Value {
    json!({
        "name": run.name,
        "shear_viscosity_pa_s": run.material.shear_viscosity,
        "bulk_viscosity_pa_s": run.material.bulk_viscosity,
        "stable_dt_s": run.stable.stable,
        "dt_s": run.dt,
        "steps": run.steps,
        "final_energies_J": run.final_energies,
        "tetra_updates_per_s": run.tetra_updates_per_s,
    })
}

/// The time step of a run from the scene: refused above the stable step unless
/// `force`, with a message naming both.
pub fn choose_time_step(
    scene_path: &Path,
    spec: &QdemSpec,
    stable: &StableTimeStep,
    force: bool,
) -> Result<f64> {
    let (dt, key) = match spec.dt {
        TimeStep::Auto => (spec.dt_factor * stable.stable, "qdem.dt_factor"),
        TimeStep::Given(dt) => (dt.si(), "qdem.dt"),
    };
    if dt > stable.stable && !force {
        return Err(Error::invalid(
            scene_path,
            format!(
                "key {key}: dt = {dt:.4e} s is {:.2} × the stable time step {:.4e} s; use \
                 dt = \"auto\" (dt = {:.4e} s) or pass --force to run it anyway",
                dt / stable.stable,
                stable.stable,
                stable.recommended()
            ),
        ));
    }
    Ok(dt)
}

fn damping(spec: Option<&DampingSpec>) -> Damping {
    match spec {
        Some(d) if d.kind == "mass_proportional" => Damping::MassProportional {
            rate: d.rate.expect("validated").si(),
        },
        Some(d) if d.kind == "kinetic" => Damping::KineticPeak,
        _ => Damping::None,
    }
}

#[allow(clippy::too_many_arguments)]
fn run_case(
    ctx: &RunContext,
    scene: &SolidScene,
    spec: &QdemSpec,
    mesh: &TetMesh,
    case: &super::scene::CaseSpec,
    dir: &Path,
    force: bool,
    timer: &mut PhaseTimer,
) -> Result<CaseRun> {
    let material = case_material(&scene.material, case);
    material
        .validate()
        .map_err(|e| Error::invalid(&ctx.scene_path, e.to_string()))?;
    let model = timer.time("model", || QdemModel::from_mesh(mesh, &material))?;
    let bc = boundary(&ctx.scene_path, scene, case, mesh)?;
    let probes = probes(&ctx.scene_path, &scene.probe, mesh)?;
    let stable = timer.time("stable step", || stability(&model));
    let dt = choose_time_step(&ctx.scene_path, spec, &stable, force)?;
    let label = if case.name.is_empty() {
        String::new()
    } else {
        format!("case {}: ", case.name)
    };
    say(format_args!(
        "ballast-qdem: {label}stable time step {:.4e} s (ω_max {:.4e} rad/s, viscous ratio \
         ξ = {:.3e}); dt = {dt:.4e} s ({:.2} × stable)",
        stable.stable,
        stable.max_angular_frequency,
        stable.damping_ratio,
        dt / stable.stable
    ));
    std::fs::create_dir_all(dir.join("frames")).map_err(|e| Error::io(dir, e))?;

    let damping_spec = spec.damping.as_ref();
    let until = damping_spec.and_then(|d| d.until).map(|t| t.si());
    let options = QdemOptions {
        damping: damping(damping_spec),
        check_time_step: false,
        ..QdemOptions::default()
    };
    let mut solver = QdemSolver::new(&model, &bc, dt, options)?;
    let mut state = State::at_rest(&model);
    solver.prime(&mut state)?;

    let duration = spec.duration.si();
    let steps = (duration / dt).ceil() as u64;
    let sample_interval = spec
        .sample_interval
        .map_or((duration / 20_000.0).max(dt), |s| s.si());
    let sample_every = ((sample_interval / dt).round() as u64).max(1);
    let frame_every = (steps / spec.frames.max(1) as u64).max(1);

    let mut output = Outputs::create(dir, mesh, &probes)?;
    output.sample(&state, &model)?;
    output.frame(&state, &solver, timer)?;

    let name = format!("ballast-qdem: {label}");
    let mut bar = Progress::steps(steps, name.trim_end_matches([':', ' ']));
    let start = Instant::now();
    let mut frames_s = 0.0;
    let mut damped = until.is_some_and(|t| t > 0.0);
    for step in 1..=steps {
        if damped && until.is_some_and(|t| state.time + 0.5 * dt >= t) {
            // Release: same state, no numerical damping from here on.
            solver = QdemSolver::new(
                &model,
                &bc,
                dt,
                QdemOptions {
                    damping: Damping::None,
                    ..options
                },
            )?;
            damped = false;
        }
        solver.step(&mut state).inspect_err(|_| bar.abandon())?;
        if step % sample_every == 0 || step == steps {
            output.sample(&state, &model)?;
            bar.set_position(step);
        }
        if step % frame_every == 0 || step == steps {
            let t = Instant::now();
            output.frame(&state, &solver, timer)?;
            frames_s += t.elapsed().as_secs_f64();
        }
    }
    bar.finish_and_clear();
    // Stepping and sampling, without the VTK frames (their own phase).
    let stepping_s = start.elapsed().as_secs_f64() - frames_s;
    timer.add("stepping", std::time::Duration::from_secs_f64(stepping_s));
    timer.add("vtk frames", std::time::Duration::from_secs_f64(frames_s));
    let e = &state.energies;
    say(format_args!(
        "ballast-qdem: {label}{steps} steps in {stepping_s:.1} s ({:.3e} tetra updates/s); \
         energy balance error {:.2e} J ({:.2e} relative)",
        steps as f64 * model.tet_count() as f64 / stepping_s,
        e.balance_error(),
        e.relative_balance_error()
    ));
    Ok(CaseRun {
        name: case.name.clone(),
        dir: dir.to_path_buf(),
        material,
        stable,
        dt,
        steps,
        probes: output.probe_series,
        final_energies: json!({
            "kinetic": e.kinetic,
            "strain": e.strain,
            "viscous_dissipated": e.viscous_dissipated,
            "damping_dissipated": e.damping_dissipated,
            "external_work": e.external_work,
            "balance_error": e.balance_error(),
        }),
        stepping_s,
        tetra_updates_per_s: steps as f64 * model.tet_count() as f64 / stepping_s,
    })
}

/// The files one case writes.
struct Outputs {
    grid: Grid,
    pvd: PvdWriter,
    frames: usize,
    probes: Vec<Probe>,
    probe_csv: CsvSeries,
    energy_csv: CsvSeries,
    probe_series: Vec<ProbeSeries>,
}

impl Outputs {
    fn create(dir: &Path, mesh: &TetMesh, probes: &[Probe]) -> Result<Self> {
        let points: Vec<[f64; 3]> = mesh.nodes.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tets: Vec<[usize; 4]> = mesh.tets.iter().map(|t| t.map(|n| n as usize)).collect();
        let grid = Grid::tetra(points, &tets)?;
        let mut columns = vec!["time_s".to_string()];
        for p in probes {
            for c in ["ux", "uy", "uz"] {
                columns.push(format!("{}_{c}_m", p.name));
            }
        }
        let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
        Ok(Outputs {
            grid,
            pvd: PvdWriter::create(dir.join("mesh.pvd"))?,
            frames: 0,
            probes: probes.to_vec(),
            probe_csv: CsvSeries::create(dir.join("probes.csv"), &columns)?,
            energy_csv: CsvSeries::create(
                dir.join("energies.csv"),
                &[
                    "time_s",
                    "kinetic_J",
                    "strain_J",
                    "viscous_dissipated_J",
                    "damping_dissipated_J",
                    "external_work_J",
                    "balance_error_J",
                ],
            )?,
            probe_series: probes
                .iter()
                .map(|p| ProbeSeries {
                    name: p.name.clone(),
                    times: Vec::new(),
                    displacements: Vec::new(),
                })
                .collect(),
        })
    }

    fn sample(&mut self, state: &State, model: &QdemModel) -> Result<()> {
        let reference = model.reference_positions();
        let mut row = vec![state.time];
        for (probe, series) in self.probes.iter().zip(&mut self.probe_series) {
            let u = probe.displacement(&state.positions, reference);
            row.extend_from_slice(&u);
            series.times.push(state.time);
            series.displacements.push(u);
        }
        self.probe_csv.push(&row)?;
        let e = &state.energies;
        self.energy_csv.push(&[
            state.time,
            e.kinetic,
            e.strain,
            e.viscous_dissipated,
            e.damping_dissipated,
            e.external_work,
            e.balance_error(),
        ])
    }

    fn frame(&mut self, state: &State, solver: &QdemSolver, timer: &mut PhaseTimer) -> Result<()> {
        let _ = timer;
        let model = solver.model();
        let mut grid = self.grid.clone();
        let u: Vec<f64> = state.displacements(model).into_iter().flatten().collect();
        let v: Vec<f64> = state.velocities.iter().flatten().copied().collect();
        grid.add_point_field("displacement_m", 3, u)?;
        grid.add_point_field("velocity_m_per_s", 3, v)?;
        let stresses = solver.stresses(state);
        let mises: Vec<f64> = stresses.iter().map(von_mises).collect();
        let flat: Vec<f64> = stresses
            .iter()
            .flat_map(|s| {
                let s = s.transpose(); // row-major for VTK's tensor layout
                s.as_slice().to_vec()
            })
            .collect();
        grid.add_cell_field("stress_Pa", 9, flat)?;
        grid.add_cell_field("von_mises_Pa", 1, mises)?;
        let rel = PathBuf::from("frames").join(format!("mesh_{:04}.vtu", self.frames));
        self.pvd.write_frame(state.time, &rel, &grid)?;
        self.frames += 1;
        Ok(())
    }
}
