//! Front ends of the solver binaries: clap structs that turn into a run context and
//! call the library.

use crate::scene::RunArgs;
use crate::solid::fem_run::{self, Analyses};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// `ballast-pack`: ballast beds by gravity deposition.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-pack",
    version,
    about = "Build a ballast bed by gravity deposition of polyhedral stones (NSCD engine): \
             a packing file, VTK and a compactness report"
)]
pub struct PackCli {
    #[command(flatten)]
    run: RunArgs,
    /// Continue a killed run from the checkpoint in its output directory DIR (give the
    /// killed run's scene, --preset and --set again; implies --out DIR). Only
    /// deposit.max_phase_time, deposit.finish_sweeps, deposit.held_warm_start,
    /// output.checkpoint_every and output.checkpoint_wall_every may differ.
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
}

/// Runs `ballast-pack`.
pub fn run_pack(cli: PackCli) -> crate::Result<()> {
    let (ctx, resume) = cli.run.resumable_context(cli.resume.as_deref())?;
    ctx.run_on_pool(|c| crate::pack::run::run(c, resume))?
}

/// `ballast-nscd`: non-smooth contact dynamics of rigid polyhedra.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-nscd",
    version,
    about = "Non-smooth contact dynamics of rigid polyhedral grains (Moreau-Jean, NLGS, \
             domain decomposition): tamping and other NSCD scenes",
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct NscdCli {
    #[command(subcommand)]
    command: Option<NscdCommand>,
    #[command(flatten)]
    run: Option<RunArgs>,
    /// Continue a killed run from the checkpoint in its output directory DIR (give the
    /// killed run's scene, --preset and --set again; implies --out DIR). Only
    /// output.checkpoint_every and output.checkpoint_wall_every may differ.
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Stop after step STEP once its checkpoint is written, without the summary:
    /// --resume continues the run. Benches use it to run versions in turns of a few
    /// hundred steps, so that the machine's slow and fast spells hit them alike.
    #[arg(long, value_name = "STEP")]
    stop_after: Option<u64>,
}

/// Sub-commands of `ballast-nscd` besides running a scene.
#[derive(Debug, Subcommand)]
pub enum NscdCommand {
    /// Solve a frictional-contact problem written by Siconos (FCLIB .dat or .hdf5).
    Fc3d {
        /// The problem file.
        file: PathBuf,
        /// Stop when the Siconos error measure falls below this.
        #[arg(long, default_value_t = 1e-8)]
        tol: f64,
        /// Cap on NSGS sweeps.
        #[arg(long, default_value_t = 10_000)]
        max_iter: usize,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

/// Runs `ballast-nscd`.
pub fn run_nscd(cli: NscdCli) -> crate::Result<()> {
    match (cli.command, cli.run) {
        (
            Some(NscdCommand::Fc3d {
                file,
                tol,
                max_iter,
                json,
            }),
            _,
        ) => super::fc3d::run(&file, tol, max_iter, json),
        (None, Some(run)) => {
            let (ctx, resume) = run.resumable_context(cli.resume.as_deref())?;
            ctx.run_on_pool(|c| crate::nscd::run::run_with(c, resume, cli.stop_after))?
        }
        (None, None) => Err(crate::Error::Message(
            "ballast-nscd: give a SCENE.toml or a sub-command (see --help)".into(),
        )),
    }
}

/// `ballast-qdem`: explicit viscoelastic tetra bodies with DEM vertex contact.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-qdem",
    version,
    about = "QDEM: tetrahedral Kelvin-Voigt viscoelastic bodies integrated explicitly, DEM \
             spheres at the vertices for contact (cantilever, creep, track impact scenes)"
)]
pub struct QdemCli {
    #[command(flatten)]
    run: RunArgs,
    /// Continue a killed track run from the checkpoint in its output directory DIR
    /// (give the killed run's scene, --preset and --set again; implies --out DIR).
    /// Only track.checkpoint_every and track.checkpoint_wall_every may differ.
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Run with a time step above the stable one (the run may blow up).
    #[arg(long)]
    force: bool,
}

/// Runs `ballast-qdem`.
pub fn run_qdem(cli: QdemCli) -> crate::Result<()> {
    let (ctx, resume) = cli.run.resumable_context(cli.resume.as_deref())?;
    let force = cli.force;
    ctx.run_on_pool(|c| {
        if crate::track::is_track_scene(&c.scene_path) {
            crate::track::run(c, force, resume)
        } else if resume {
            Err(crate::Error::Message(format!(
                "--resume: {} is not a track scene (only track scenes checkpoint)",
                c.scene_path.display()
            )))
        } else {
            crate::solid::qdem_run::run(c, force)
        }
    })?
}

/// `ballast-fem`: the linear-tetra reference solver.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-fem",
    version,
    about = "Reference linear-elastic FEM on the same tetra meshes: static solve and lowest \
             vibration modes (sparse Cholesky, shift-invert)"
)]
pub struct FemCli {
    #[command(subcommand)]
    command: FemCommand,
}

/// What `ballast-fem` computes.
#[derive(Debug, Subcommand)]
pub enum FemCommand {
    /// Static displacement under the scene's loads.
    Static(RunArgs),
    /// Lowest vibration modes and frequencies.
    Modes(RunArgs),
    /// Both in one process: one assembly and ordering, and on a held body the static
    /// solve's Cholesky factor of K reused by the eigen-solver (shift 0).
    Both(RunArgs),
}

/// Runs `ballast-fem`.
pub fn run_fem(cli: FemCli) -> crate::Result<()> {
    match cli.command {
        FemCommand::Static(run) => fem_run::run(&run.context()?, Analyses::Static),
        FemCommand::Modes(run) => fem_run::run(&run.context()?, Analyses::Modes),
        FemCommand::Both(run) => fem_run::run(&run.context()?, Analyses::Both),
    }
}
