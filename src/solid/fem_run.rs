//! `ballast-fem static|modes|both SCENE.toml`: the reference linear-elastic FEM run on the
//! same scene file as `ballast-qdem` (same mesh, groups, loads and probes), through the
//! numerical core in [`crate::fem`].
//!
//! - `static`: the scene's `[[fix]]` groups hold the named directions at zero (a
//!   partially fixed group prescribes only its components), every `[[load]]` puts
//!   total force / node count on each node of its group exactly as QDEM does (its time
//!   function is ignored: the full force), gravity adds ρV/4 per tetra vertex, and
//!   `[[fem.winkler]]` beds act as grounded springs. One sparse Cholesky solve.
//! - `modes`: the lowest `[fem] modes` eigenpairs of K φ = ω² M φ (consistent mass)
//!   with the same fixes and springs. When they do not hold the body (free–free: no
//!   fixes and no springs) the rigid-body modes (|f| < 10⁻³ × the highest frequency
//!   computed, six for one free body) are computed too, skipped and reported as such.
//!
//! - `both`: the two in one process on one assembled system per case. The ordering and
//!   symbolic factor are computed once and, on a held body, the eigen-solver runs with
//!   shift 0 on the static solve's factor of K: at the paper's resolution that removes a
//!   second factorisation, the costliest phase (see `make compare-fem`).
//!
//! A scene with `[[case]]`s is run once per case (one sub-directory each) only when a
//! case adds fixes; viscosities do not enter linear elasticity, so cases that differ
//! only in them give one run.
//!
//! Outputs, in the output directory:
//! - static: `static.vtu` (point field `displacement_m`, cell fields `stress_Pa`, nine
//!   components row-major, and `von_mises_Pa`), `probes.csv` (one row,
//!   `<probe>_ux_m`, `<probe>_uy_m`, `<probe>_uz_m` as in QDEM's file, without its time
//!   column) and `summary.json` with `tip_deflection_m` (|u| at the `[analysis]` probe
//!   for `kind = "static_deflection"`) or `<probe>_displacement_m` per probe;
//! - modes: `modes.pvd` with one frame per mode (`modes/mode_NN.vtu`, "time" = mode
//!   number, point field `displacement_m` = the mode shape scaled to max |u| = 1),
//!   `frequencies.csv` (`mode`, `frequency_hz`) and `summary.json` with
//!   `frequencies_hz`, `first_frequency_hz` and a description of each mode shape.
//!
//! Mode shapes are described along the body's longest bounding-box axis s: the nodes are
//! binned into slices across s, and the mass-weighted mean displacement of each slice
//! ū(s) is the centre-line motion. The fraction of the mode's kinetic energy measure
//! Σ m|u|² carried by each component of ū (Σ m ū_c² / Σ m |u|²) says whether the mode
//! is vertical bending (ū_z, z up), lateral bending (the other transverse component),
//! axial (ū_s) or torsion / cross-section deformation (the remainder, which a slice
//! mean cancels); the largest fraction names the kind. For vertical modes the sign
//! changes of ū_z(s) count the nodes of the shape: with no fixes (a free body or one on
//! springs) 0 is a rigid bounce, 1 a rigid pitch, 2 the first vertical bending mode
//! (symmetric along s), 3 the second (antisymmetric), 4 the third (symmetric).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Vector3};
use serde_json::{json, Map, Value};

use super::scene::{CaseSpec, SolidScene};
use super::setup::{case_fixes, group_nodes, probes, Probe};
use crate::fem::{
    DofSet, FemModel, FemSystem, LinearElastic, ModeOptions, Modes, PhaseTimes, Springs,
};
use crate::mesh::{read_msh, TetMesh};
use crate::output::vtu::vtu_bytes;
use crate::output::{write_atomic, write_json, write_vtu, CsvSeries, Grid, PvdWriter};
use crate::qdem::von_mises;
use crate::scene::{PhaseTimer, RunContext, Summary};
use crate::{Error, Result};
use rayon::prelude::*;

/// Modes below this fraction of the highest frequency computed count as rigid-body
/// modes when the supports do not hold the body.
const RIGID_FREQUENCY_FRACTION: f64 = 1e-3;

/// Slices along the long axis for the centre-line description of a mode shape.
const SHAPE_SLICES: usize = 40;

/// Centre-line values below this fraction of their largest magnitude are ignored when
/// counting sign changes (the slices next to a node of the shape).
const SIGN_CHANGE_FLOOR: f64 = 0.05;

/// Which analyses one `ballast-fem` process runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Analyses {
    /// `ballast-fem static`.
    Static,
    /// `ballast-fem modes`.
    Modes,
    /// `ballast-fem both`: the static solve, then the modes, on one assembled system per
    /// case: assembly and ordering are done once, and on a held body (shift σ = 0) the
    /// eigen-solver reuses the static solve's Cholesky factor of K.
    Both,
}

impl Analyses {
    fn command(self) -> &'static str {
        match self {
            Analyses::Static => "static",
            Analyses::Modes => "modes",
            Analyses::Both => "both",
        }
    }

    fn statics(self) -> bool {
        self != Analyses::Modes
    }

    fn modes(self) -> bool {
        self != Analyses::Static
    }
}

/// Runs `ballast-fem static`, `modes` or `both`.
pub fn run(ctx: &RunContext, analyses: Analyses) -> Result<()> {
    let mut run = FemSetup::new(ctx, analyses.command())?;
    let springs = springs(ctx, &run.scene, &run.mesh)?;
    let (loads, probes) = if analyses.statics() {
        (
            nodal_loads(ctx, &run.scene, &run.mesh, &run.model)?,
            probes(&ctx.scene_path, &run.scene.probe, &run.mesh)?,
        )
    } else {
        (Vec::new(), Vec::new())
    };
    let count = run.scene.fem.as_ref().map_or(4, |f| f.modes);
    let cases = fem_cases(&run.scene);
    let fixes = case_fixes_all(ctx, &run, &cases)?;
    let mut static_runs = Vec::new();
    let mut modes_runs = Vec::new();
    for (case, fixed) in cases.iter().zip(&fixes) {
        let dir = case_dir(ctx, case);
        let mut system = run.model.system(fixed, springs.as_ref())?;
        let mut timings = PhaseTimes::default();
        let mut output = Duration::ZERO;
        if analyses.statics() {
            let r = static_case(ctx, &run, &mut system, case, fixed, &loads, &probes, &dir)?;
            accumulate(&mut timings, &r.timings);
            output += r.output;
            static_runs.push(r);
        }
        if analyses.modes() {
            let r = modes_case(ctx, &run, &mut system, case, fixed, count, &dir)?;
            accumulate(&mut timings, &r.timings);
            output += r.output;
            modes_runs.push(r);
        }
        drop(system);
        run.add_times(&timings);
        run.timer.add("output", output);
    }

    let (free_dofs, fixed_dofs, matrix_nnz, factor_nnz, solver_s) =
        match (static_runs.first(), modes_runs.first()) {
            (Some(s), m) => (
                s.free_dofs,
                s.fixed_dofs,
                s.matrix_nnz,
                s.factor_nnz,
                s.timings.total_s() + m.map_or(0.0, |m| m.timings.total_s()),
            ),
            (None, Some(m)) => (
                m.free_dofs,
                m.fixed_dofs,
                m.matrix_nnz,
                m.factor_nnz,
                m.timings.total_s(),
            ),
            (None, None) => unreachable!("at least one case and one analysis"),
        };
    let mut summary = run
        .summary(ctx)
        .figure("free_dofs", free_dofs)
        .figure("fixed_dofs", fixed_dofs)
        .figure("matrix_nnz", matrix_nnz)
        .figure("factor_nnz", factor_nnz);
    if let Some(first) = static_runs.first() {
        let total_load: Vector3<f64> = loads.iter().sum();
        summary = summary
            .figure("applied_load_N", vec3_json(&total_load))
            .figure("reaction_total_N", vec3_json(&first.reaction_total))
            .figure("max_displacement_m", first.max_displacement)
            .figure("max_von_mises_Pa", first.max_von_mises);
        for (name, value) in static_figures(&run.scene, first) {
            summary = summary.figure(&name, value);
        }
    }
    if let Some(first) = modes_runs.first() {
        summary = summary.figure(
            "winkler_total_stiffness_N_per_m",
            springs.as_ref().map_or(0.0, |s| s.total().trace()),
        );
        for (name, value) in modes_figures(&run.scene, first) {
            summary = summary.figure(&name, value);
        }
    }
    summary = summary.figure("solver_wall_time_s", solver_s);
    if cases.len() > 1 {
        let per_case: Vec<Value> = cases
            .iter()
            .enumerate()
            .map(|(i, case)| {
                let mut figures = Map::new();
                figures.insert("name".into(), json!(case.name));
                if let Some(r) = static_runs.get(i) {
                    figures.insert("free_dofs".into(), json!(r.free_dofs));
                    figures.extend(static_figures(&run.scene, r));
                }
                if let Some(r) = modes_runs.get(i) {
                    figures.extend(modes_figures(&run.scene, r));
                }
                Value::Object(figures)
            })
            .collect();
        summary = summary.figure("cases", per_case);
    }
    if let Some(note) = run.cases_note() {
        summary = summary.figure("cases_note", note);
    }
    run.finish(ctx, summary)
}

/// What both commands read first: the scene, the mesh and the model.
struct FemSetup {
    command: &'static str,
    /// The first progress line, until printed.
    announcement: std::cell::Cell<Option<String>>,
    scene: SolidScene,
    inputs: toml::Table,
    mesh: TetMesh,
    model: FemModel,
    timer: PhaseTimer,
}

impl FemSetup {
    fn new(ctx: &RunContext, command: &'static str) -> Result<Self> {
        let threads = ctx.configure_threads()?;
        let mut timer = PhaseTimer::new();
        let (scene, inputs): (SolidScene, _) = timer.time("read scene", || ctx.load_scene())?;
        let mesh_path = SolidScene::resolve(&ctx.scene_path, &scene.mesh.file);
        let mesh = timer.time("read mesh", || read_msh(&mesh_path))?;
        let material = LinearElastic {
            young_modulus: scene.material.young_modulus.si(),
            poisson: scene.material.poisson,
            density: scene.material.density.si(),
        };
        let model = timer
            .time("model", || FemModel::new(&mesh.nodes, &mesh.tets, material))
            .map_err(|e| Error::invalid(&mesh_path, e.to_string()))?;
        std::fs::create_dir_all(&ctx.out_dir).map_err(|e| Error::io(&ctx.out_dir, e))?;
        // Printed once every input is resolved, so that a bad scene gives one line.
        let announcement = format!(
            "ballast-fem {command}: {} — {} nodes, {} tetra, {threads} threads",
            mesh_path.display(),
            mesh.nodes.len(),
            mesh.tets.len()
        );
        Ok(FemSetup {
            command,
            announcement: std::cell::Cell::new(Some(announcement)),
            scene,
            inputs,
            mesh,
            model,
            timer,
        })
    }

    /// Prints the first progress line (once).
    fn announce(&self) {
        if let Some(line) = self.announcement.take() {
            eprintln!("{line}");
        }
    }

    fn summary(&self, ctx: &RunContext) -> Summary {
        Summary::new(ctx, &self.inputs)
            .figure("command", self.command)
            .figure("nodes", self.mesh.nodes.len())
            .figure("tetra", self.mesh.tets.len())
            .figure("dofs", 3 * self.mesh.nodes.len())
            .figure("mass_kg", self.model.mass())
    }

    fn cases_note(&self) -> Option<String> {
        (!self.scene.case.is_empty() && fem_cases(&self.scene).len() == 1).then(|| {
            format!(
                "the scene's {} [[case]]s differ only in viscosities, which linear \
                 elasticity ignores: one run",
                self.scene.case.len()
            )
        })
    }

    fn finish(self, ctx: &RunContext, summary: Summary) -> Result<()> {
        let summary = summary.wall_times(&self.timer);
        let path = ctx.out_dir.join("summary.json");
        write_json(&path, &summary.to_json())?;
        eprintln!("ballast-fem {}: wrote {}", self.command, path.display());
        Ok(())
    }

    fn add_times(&mut self, times: &PhaseTimes) {
        for (phase, seconds) in [
            ("assembly", times.assembly_s),
            ("ordering", times.ordering_s),
            ("factorisation", times.factorisation_s),
            ("solve", times.solve_s),
            ("eigen", times.eigen_s),
        ] {
            if seconds > 0.0 {
                self.timer.add(phase, Duration::from_secs_f64(seconds));
            }
        }
    }

    fn grid(&self) -> Result<Grid> {
        let points: Vec<[f64; 3]> = self.mesh.nodes.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tets: Vec<[usize; 4]> = self
            .mesh
            .tets
            .iter()
            .map(|t| t.map(|n| n as usize))
            .collect();
        Grid::tetra(points, &tets)
    }
}

/// The runs a scene asks for: one per case when a case adds fixes, else one.
fn fem_cases(scene: &SolidScene) -> Vec<CaseSpec> {
    if scene.case.iter().any(|c| !c.fix.is_empty()) {
        scene.case.clone()
    } else {
        vec![CaseSpec {
            name: String::new(),
            shear_viscosity: None,
            bulk_viscosity: None,
            fix: Vec::new(),
        }]
    }
}

fn case_dir(ctx: &RunContext, case: &CaseSpec) -> PathBuf {
    if case.name.is_empty() {
        ctx.out_dir.clone()
    } else {
        ctx.out_dir.join(&case.name)
    }
}

fn case_label(case: &CaseSpec) -> String {
    if case.name.is_empty() {
        String::new()
    } else {
        format!("case {}: ", case.name)
    }
}

/// The fixed directions of a case, each one prescribed to zero per component.
fn fixed_dofs(
    ctx: &RunContext,
    scene: &SolidScene,
    case: &CaseSpec,
    mesh: &TetMesh,
) -> Result<DofSet> {
    let mut set = DofSet::new();
    for (key, fix) in case_fixes(scene, case) {
        let mask = fix.mask().expect("validated");
        for &node in group_nodes(&ctx.scene_path, mesh, &key, &fix.group)? {
            for component in (0..3).filter(|&c| mask.contains(c)) {
                set.prescribe(node, component, 0.0);
            }
        }
    }
    Ok(set)
}

/// The fixed DOFs of every case, resolved before any solve.
fn case_fixes_all(ctx: &RunContext, run: &FemSetup, cases: &[CaseSpec]) -> Result<Vec<DofSet>> {
    cases
        .iter()
        .map(|case| fixed_dofs(ctx, &run.scene, case, &run.mesh))
        .collect()
}

/// The `[[fem.winkler]]` beds as grounded springs (none without any).
fn springs(ctx: &RunContext, scene: &SolidScene, mesh: &TetMesh) -> Result<Option<Springs>> {
    let Some(fem) = scene.fem.as_ref().filter(|f| !f.winkler.is_empty()) else {
        return Ok(None);
    };
    let mut springs = Springs::new();
    for (i, bed) in fem.winkler.iter().enumerate() {
        let key = format!("fem.winkler[{i}]");
        group_nodes(&ctx.scene_path, mesh, &key, &bed.group)?;
        let group = mesh.group(&bed.group).expect("checked above");
        if group.triangles.is_empty() {
            return Err(Error::invalid(
                &ctx.scene_path,
                format!(
                    "key {key}.group: group \"{}\" of {} has no surface triangles (a Winkler \
                     bed needs a physical surface)",
                    bed.group,
                    mesh.source.display()
                ),
            ));
        }
        springs.add_winkler(&mesh.nodes, &group.triangles, bed.stiffness.si());
    }
    Ok(Some(springs))
}

/// Nodal forces: each load's total force / node count on every node of its group (as
/// QDEM spreads it; the time function is ignored), plus gravity as ρV/4 per vertex.
fn nodal_loads(
    ctx: &RunContext,
    scene: &SolidScene,
    mesh: &TetMesh,
    model: &FemModel,
) -> Result<Vec<Vector3<f64>>> {
    let mut loads = vec![Vector3::zeros(); mesh.nodes.len()];
    for (i, load) in scene.load.iter().enumerate() {
        let nodes = group_nodes(&ctx.scene_path, mesh, &format!("load[{i}]"), &load.group)?;
        let total = Vector3::new(load.force[0].si(), load.force[1].si(), load.force[2].si());
        let share = total / nodes.len() as f64;
        for &n in nodes {
            loads[n as usize] += share;
        }
    }
    if let Some(g) = &scene.gravity {
        let g = Vector3::new(g[0].si(), g[1].si(), g[2].si());
        let density = model.material().density;
        for (tet, geometry) in model.tets().iter().zip(model.geometry()) {
            let force = g * (density * geometry.volume / 4.0);
            for &n in tet {
                loads[n as usize] += force;
            }
        }
    }
    Ok(loads)
}

fn vec3_json(v: &Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

/// Mean displacement over a probe's nodes.
fn probe_displacement(probe: &Probe, displacement: &[Vector3<f64>]) -> Vector3<f64> {
    let sum: Vector3<f64> = probe.nodes.iter().map(|&n| displacement[n as usize]).sum();
    sum / probe.nodes.len() as f64
}

/// One static solve.
struct StaticRun {
    free_dofs: usize,
    fixed_dofs: usize,
    matrix_nnz: usize,
    factor_nnz: usize,
    probes: Vec<(String, Vector3<f64>)>,
    reaction_total: Vector3<f64>,
    max_displacement: f64,
    max_von_mises: f64,
    timings: PhaseTimes,
    /// Time spent writing the outputs.
    output: Duration,
}

#[allow(clippy::too_many_arguments)]
fn static_case(
    ctx: &RunContext,
    run: &FemSetup,
    system: &mut FemSystem<'_>,
    case: &CaseSpec,
    fixed: &DofSet,
    loads: &[Vector3<f64>],
    probes: &[Probe],
    dir: &Path,
) -> Result<StaticRun> {
    let label = case_label(case);
    let springs = run
        .scene
        .fem
        .as_ref()
        .is_some_and(|f| !f.winkler.is_empty());
    if !system.is_anchored() {
        return Err(Error::invalid(
            &ctx.scene_path,
            format!(
                "key fix: {label}the [[fix]] groups{} leave the body free to move as a rigid \
                 body; a static solve needs supports that hold it",
                if springs {
                    " and [[fem.winkler]] beds"
                } else {
                    " (there is no [[fem.winkler]] bed)"
                }
            ),
        ));
    }
    run.announce();
    let (free_dofs, matrix_nnz, factor_nnz) = (
        system.free_dof_count(),
        system.matrix_nnz(),
        system.factor_nnz(),
    );
    let solution = system.static_solve(loads)?;
    let u = &solution.displacement;

    let start = Instant::now();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let stresses = run.model.tet_stress(u);
    let mises: Vec<f64> = stresses.iter().map(von_mises).collect();
    let mut grid = run.grid()?;
    grid.add_point_field(
        "displacement_m",
        3,
        u.iter().flat_map(|v| [v.x, v.y, v.z]).collect::<Vec<f64>>(),
    )?;
    grid.add_cell_field("stress_Pa", 9, row_major(&stresses))?;
    grid.add_cell_field("von_mises_Pa", 1, mises.clone())?;
    write_vtu(dir.join("static.vtu"), &grid)?;

    let probe_values: Vec<(String, Vector3<f64>)> = probes
        .iter()
        .map(|p| (p.name.clone(), probe_displacement(p, u)))
        .collect();
    let mut columns = Vec::new();
    for p in probes {
        for c in ["ux", "uy", "uz"] {
            columns.push(format!("{}_{c}_m", p.name));
        }
    }
    let columns: Vec<&str> = columns.iter().map(String::as_str).collect();
    let mut csv = CsvSeries::create(dir.join("probes.csv"), &columns)?;
    if !probes.is_empty() {
        let row: Vec<f64> = probe_values
            .iter()
            .flat_map(|(_, v)| [v.x, v.y, v.z])
            .collect();
        csv.push(&row)?;
    }
    let output = start.elapsed();

    let max_displacement = u.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let max_von_mises = mises.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "ballast-fem static: {label}{free_dofs} unknowns, max |u| {max_displacement:.4e} m, \
         max von Mises {max_von_mises:.4e} Pa; {}",
        solution.timings
    );
    for (name, v) in &probe_values {
        eprintln!(
            "ballast-fem static: {label}probe {name}: u = ({:.6e}, {:.6e}, {:.6e}) m, |u| = \
             {:.6e} m",
            v.x,
            v.y,
            v.z,
            v.norm()
        );
    }
    Ok(StaticRun {
        free_dofs,
        fixed_dofs: fixed.len(),
        matrix_nnz,
        factor_nnz,
        probes: probe_values,
        reaction_total: solution.reactions.iter().sum(),
        max_displacement,
        max_von_mises,
        timings: solution.timings,
        output,
    })
}

/// Stress tensors flattened row by row (VTK's tensor layout).
fn row_major(tensors: &[Matrix3<f64>]) -> Vec<f64> {
    tensors
        .iter()
        .flat_map(|s| s.transpose().as_slice().to_vec())
        .collect()
}

/// The figures of a static run: the probes, and the scene's analysis.
fn static_figures(scene: &SolidScene, run: &StaticRun) -> Vec<(String, Value)> {
    let mut figures = Vec::new();
    let probes: Map<String, Value> = run
        .probes
        .iter()
        .map(|(name, v)| {
            (
                name.clone(),
                json!({"ux_m": v.x, "uy_m": v.y, "uz_m": v.z, "magnitude_m": v.norm()}),
            )
        })
        .collect();
    figures.push(("probes".into(), Value::Object(probes)));
    match scene
        .analysis
        .as_ref()
        .filter(|a| a.kind == "static_deflection")
    {
        Some(analysis) => {
            let u = run
                .probes
                .iter()
                .find(|(name, _)| *name == analysis.probe)
                .map(|(_, v)| *v)
                .expect("validated probe name");
            figures.push(("tip_deflection_m".into(), json!(u.norm())));
            figures.push(("tip_deflection_z_m".into(), json!(u.z)));
            reference_figures(scene, u.norm(), &mut figures);
        }
        None => {
            for (name, v) in &run.probes {
                figures.push((format!("{name}_displacement_m"), json!(v.norm())));
            }
        }
    }
    figures
}

/// `reference` and the relative error against it, as QDEM's analysis reports them.
fn reference_figures(scene: &SolidScene, value: f64, figures: &mut Vec<(String, Value)>) {
    let Some(spec) = &scene.analysis else {
        return;
    };
    if let Some(r) = spec.reference {
        figures.push(("reference".into(), json!(r)));
        figures.push(("relative_error_vs_reference".into(), json!((value - r) / r)));
        if let Some(source) = &spec.reference_source {
            figures.push(("reference_source".into(), json!(source)));
        }
    }
}

/// How a mode shape moves, along the body's longest axis (see the module docs).
#[derive(Debug, Clone)]
struct ShapeCharacter {
    /// Fraction of Σ m|u|² in the slice-mean motion, per component x, y, z.
    centreline: [f64; 3],
    /// The rest: torsion and cross-section deformation.
    other: f64,
    /// Sign changes along the long axis of the slice-mean motion component that names
    /// the kind (ū_z for vertical bending); none for torsion and other shapes.
    sign_changes: Option<usize>,
    /// `vertical_bending`, `lateral_bending`, `axial` or `torsion_or_other` (with a
    /// vertical long axis: `bending_x`, `bending_y`, `axial`, `torsion_or_other`).
    kind: &'static str,
}

impl ShapeCharacter {
    fn new(model: &FemModel, shape: &[Vector3<f64>]) -> Self {
        let nodes = model.nodes();
        let mut mass = vec![0.0; nodes.len()];
        for (tet, geometry) in model.tets().iter().zip(model.geometry()) {
            for &n in tet {
                mass[n as usize] += geometry.volume / 4.0;
            }
        }
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        );
        for p in nodes {
            lo = lo.inf(&p.coords);
            hi = hi.sup(&p.coords);
        }
        let extent = hi - lo;
        let axis = extent.imax();
        let slices = SHAPE_SLICES.min((nodes.len() / 10).max(1));
        let slice_of = |x: f64| {
            let s = ((x - lo[axis]) / extent[axis] * slices as f64).floor();
            (s.max(0.0) as usize).min(slices - 1)
        };
        let mut slice_mass = vec![0.0; slices];
        let mut slice_momentum = vec![Vector3::zeros(); slices];
        let mut total = 0.0;
        for ((p, u), &m) in nodes.iter().zip(shape).zip(&mass) {
            let s = slice_of(p[axis]);
            slice_mass[s] += m;
            slice_momentum[s] += u * m;
            total += m * u.norm_squared();
        }
        let means: Vec<Vector3<f64>> = slice_momentum
            .iter()
            .zip(&slice_mass)
            .map(|(p, &m)| if m > 0.0 { p / m } else { Vector3::zeros() })
            .collect();
        let mut centreline = [0.0; 3];
        for (mean, &m) in means.iter().zip(&slice_mass) {
            for (c, value) in centreline.iter_mut().enumerate() {
                *value += m * mean[c] * mean[c];
            }
        }
        let centreline = centreline.map(|v| if total > 0.0 { v / total } else { 0.0 });
        let other = (1.0 - centreline.iter().sum::<f64>()).max(0.0);
        let names: [&'static str; 3] = if axis == 2 {
            ["bending_x", "bending_y", "axial"]
        } else {
            let mut names = ["lateral_bending"; 3];
            names[axis] = "axial";
            names[2] = "vertical_bending";
            names
        };
        let mut kind = "torsion_or_other";
        let mut dominant = None;
        let mut best = other;
        for (c, &fraction) in centreline.iter().enumerate() {
            if fraction > best {
                best = fraction;
                kind = names[c];
                dominant = Some(c);
            }
        }
        let sign_changes = dominant.map(|c| {
            let values: Vec<f64> = means
                .iter()
                .zip(&slice_mass)
                .filter(|(_, &m)| m > 0.0)
                .map(|(u, _)| u[c])
                .collect();
            let floor = SIGN_CHANGE_FLOOR * values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let signs: Vec<bool> = values
                .iter()
                .filter(|v| v.abs() > floor)
                .map(|&v| v > 0.0)
                .collect();
            signs.windows(2).filter(|w| w[0] != w[1]).count()
        });
        ShapeCharacter {
            centreline,
            other,
            sign_changes,
            kind,
        }
    }

    fn to_json(&self) -> Value {
        json!({
            "kind": self.kind,
            "centreline_fraction_xyz": self.centreline,
            "torsion_or_other_fraction": self.other,
            "centreline_sign_changes": self.sign_changes,
        })
    }
}

/// One eigen-solve.
struct ModesRun {
    free_dofs: usize,
    fixed_dofs: usize,
    matrix_nnz: usize,
    factor_nnz: usize,
    /// Whether the case has fixes (otherwise a free body, or one on springs only).
    has_fixes: bool,
    /// Whether the body rests on springs.
    has_springs: bool,
    frequencies: Vec<f64>,
    residuals: Vec<f64>,
    shapes: Vec<ShapeCharacter>,
    rigid_frequencies: Vec<f64>,
    iterations: usize,
    solves: usize,
    shift: f64,
    timings: PhaseTimes,
    /// Time spent writing the outputs.
    output: Duration,
}

fn modes_case(
    ctx: &RunContext,
    run: &FemSetup,
    system: &mut FemSystem<'_>,
    case: &CaseSpec,
    fixed: &DofSet,
    count: usize,
    dir: &Path,
) -> Result<ModesRun> {
    let label = case_label(case);
    let has_springs = run
        .scene
        .fem
        .as_ref()
        .is_some_and(|f| !f.winkler.is_empty());
    let anchored = system.is_anchored();
    let (free_dofs, matrix_nnz, factor_nnz) = (
        system.free_dof_count(),
        system.matrix_nnz(),
        system.factor_nnz(),
    );
    if count > free_dofs {
        return Err(Error::invalid(
            &ctx.scene_path,
            format!("key fem.modes: {count} modes asked for a model of {free_dofs} free DOFs"),
        ));
    }
    run.announce();
    let options = ModeOptions::default();
    let mut wanted = if anchored { count } else { count + 6 };
    let mut timings = PhaseTimes::default();
    let (modes, rigid) = loop {
        let modes: Modes = system.modes(wanted.min(free_dofs), &options)?;
        accumulate(&mut timings, &modes.timings);
        let highest = modes
            .frequencies_hz
            .iter()
            .fold(0.0f64, |a, f| a.max(f.abs()));
        let rigid: Vec<usize> = if anchored {
            Vec::new()
        } else {
            (0..modes.frequencies_hz.len())
                .filter(|&i| modes.frequencies_hz[i].abs() < RIGID_FREQUENCY_FRACTION * highest)
                .collect()
        };
        let elastic = modes.frequencies_hz.len() - rigid.len();
        if elastic >= count || wanted >= free_dofs {
            break (modes, rigid);
        }
        wanted = (count + rigid.len() + 6).max(wanted + 6);
        if wanted > 4 * count + 48 {
            return Err(Error::invalid(
                &ctx.scene_path,
                format!(
                    "key fix: {label}{} rigid-body modes found: the body is not held and \
                     seems to be in several pieces",
                    rigid.len()
                ),
            ));
        }
    };
    let elastic: Vec<usize> = (0..modes.frequencies_hz.len())
        .filter(|i| !rigid.contains(i))
        .take(count)
        .collect();
    if elastic.len() < count {
        return Err(Error::Message(format!(
            "ballast-fem modes: {label}only {} elastic modes found of the {count} asked",
            elastic.len()
        )));
    }

    let start = Instant::now();
    std::fs::create_dir_all(dir.join("modes")).map_err(|e| Error::io(dir, e))?;
    let grid = run.grid()?;
    // The frames are encoded in parallel (zlib is most of a frame's cost), then written
    // and listed in mode order.
    let frames: Vec<(PathBuf, Vec<u8>)> = elastic
        .par_iter()
        .enumerate()
        .map(|(number, &i)| {
            let shape = &modes.shapes[i];
            let scale = shape.iter().fold(0.0f64, |a, u| a.max(u.norm()));
            let scale = if scale > 0.0 { 1.0 / scale } else { 1.0 };
            let mut frame = grid.clone();
            frame.add_point_field(
                "displacement_m",
                3,
                shape
                    .iter()
                    .flat_map(|u| [u.x * scale, u.y * scale, u.z * scale])
                    .collect::<Vec<f64>>(),
            )?;
            let file = PathBuf::from("modes").join(format!("mode_{:02}.vtu", number + 1));
            Ok((file, vtu_bytes(&frame)?))
        })
        .collect::<Result<_>>()?;
    let mut pvd = PvdWriter::create(dir.join("modes.pvd"))?;
    let mut csv = CsvSeries::create(dir.join("frequencies.csv"), &["mode", "frequency_hz"])?;
    for (number, ((file, bytes), &i)) in frames.iter().zip(&elastic).enumerate() {
        write_atomic(dir.join(file), bytes)?;
        pvd.add_frame((number + 1) as f64, file)?;
        csv.push(&[(number + 1) as f64, modes.frequencies_hz[i]])?;
    }
    let shapes: Vec<ShapeCharacter> = elastic
        .iter()
        .map(|&i| ShapeCharacter::new(&run.model, &modes.shapes[i]))
        .collect();
    let output = start.elapsed();

    let frequencies: Vec<f64> = elastic.iter().map(|&i| modes.frequencies_hz[i]).collect();
    let rigid_frequencies: Vec<f64> = rigid.iter().map(|&i| modes.frequencies_hz[i]).collect();
    if !rigid.is_empty() {
        eprintln!(
            "ballast-fem modes: {label}the supports do not hold the body: {} rigid-body modes \
             (|f| < {:.2e} Hz) skipped",
            rigid.len(),
            rigid_frequencies.iter().fold(0.0f64, |a, f| a.max(f.abs()))
        );
    }
    let list: Vec<String> = frequencies
        .iter()
        .zip(&shapes)
        .map(|(f, s)| format!("{f:.4} Hz ({})", s.kind))
        .collect();
    eprintln!(
        "ballast-fem modes: {label}{}; {} block steps, {} solves; {timings}",
        list.join(", "),
        modes.iterations,
        modes.solves
    );
    Ok(ModesRun {
        free_dofs,
        fixed_dofs: fixed.len(),
        matrix_nnz,
        factor_nnz,
        has_fixes: !fixed.is_empty(),
        has_springs,
        frequencies,
        residuals: elastic.iter().map(|&i| modes.residuals[i]).collect(),
        shapes,
        rigid_frequencies,
        iterations: modes.iterations,
        solves: modes.solves,
        shift: modes.shift,
        timings,
        output,
    })
}

fn accumulate(total: &mut PhaseTimes, add: &PhaseTimes) {
    total.assembly_s += add.assembly_s;
    total.ordering_s += add.ordering_s;
    total.factorisation_s += add.factorisation_s;
    total.solve_s += add.solve_s;
    total.eigen_s += add.eigen_s;
}

/// The figures of a modes run.
fn modes_figures(scene: &SolidScene, run: &ModesRun) -> Vec<(String, Value)> {
    let mut figures = vec![
        ("frequencies_hz".to_string(), json!(run.frequencies)),
        ("first_frequency_hz".to_string(), json!(run.frequencies[0])),
    ];
    let modes: Vec<Value> = run
        .frequencies
        .iter()
        .zip(&run.shapes)
        .zip(&run.residuals)
        .enumerate()
        .map(|(i, ((f, shape), residual))| {
            json!({
                "mode": i + 1,
                "frequency_hz": f,
                "residual": residual,
                "shape": shape.to_json(),
            })
        })
        .collect();
    figures.push(("modes".into(), Value::Array(modes)));
    // Vertical bending: with fixes, every vertical mode; without (free, or on springs),
    // shapes with fewer than two sign changes are a rigid bounce or pitch.
    let min_changes = if run.has_fixes { 0 } else { 2 };
    let vertical = |rigid: bool| -> Vec<f64> {
        run.frequencies
            .iter()
            .zip(&run.shapes)
            .filter(|(_, s)| {
                s.kind == "vertical_bending" && (s.sign_changes.unwrap_or(0) < min_changes) == rigid
            })
            .map(|(f, _)| *f)
            .collect()
    };
    figures.push((
        "vertical_bending_frequencies_hz".into(),
        json!(vertical(false)),
    ));
    if !run.has_fixes && run.has_springs {
        figures.push((
            "vertical_rigid_body_frequencies_hz".into(),
            json!(vertical(true)),
        ));
    }
    figures.push((
        "rigid_body_modes_skipped".into(),
        json!(run.rigid_frequencies.len()),
    ));
    if !run.rigid_frequencies.is_empty() {
        figures.push((
            "rigid_body_frequencies_hz".into(),
            json!(run.rigid_frequencies),
        ));
        figures.push((
            "rigid_body_note".into(),
            json!(format!(
                "the supports do not hold the body (free–free when there are no fixes and \
                 no springs): its {} rigid-body modes (|f| below {RIGID_FREQUENCY_FRACTION} × \
                 the highest frequency computed) are skipped; frequencies_hz lists elastic \
                 modes only",
                run.rigid_frequencies.len()
            )),
        ));
    }
    figures.push(("eigen_block_steps".into(), json!(run.iterations)));
    figures.push(("eigen_solves".into(), json!(run.solves)));
    figures.push(("eigen_shift_rad2_per_s2".into(), json!(run.shift)));
    if scene
        .analysis
        .as_ref()
        .is_some_and(|a| a.kind == "frequency")
    {
        reference_figures(scene, run.frequencies[0], &mut figures);
    }
    figures
}
