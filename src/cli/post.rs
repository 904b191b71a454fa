//! `ballast-post`: reports and charts from meshes and results.

use crate::scene::RunArgs;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// `ballast-post`: post-processing of meshes and results.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-post",
    version,
    about = "Post-processing: mesh gallery (VTK + quality table), stone-family statistics \
             against the real grain library; later spectra, compactness and charts"
)]
pub struct PostCli {
    #[command(subcommand)]
    command: PostCommand,
}

/// What `ballast-post` does.
#[derive(Debug, Subcommand)]
pub enum PostCommand {
    /// Run a mesh-gallery scene: check every mesh, export VTK, print the quality table.
    Meshes(RunArgs),
    /// Shape and grading statistics of a stone family beside the real grain library.
    Stones {
        /// Directory of stone meshes (stone_*.msh).
        dir: PathBuf,
        /// The grain library (BIBLIGRAINS.DAT) to compare with.
        #[arg(long)]
        library: Option<PathBuf>,
    },
}

/// Runs `ballast-post`.
pub fn run_post(cli: PostCli) -> crate::Result<()> {
    match cli.command {
        PostCommand::Meshes(run) => {
            let ctx = run.context()?;
            ctx.configure_threads()?;
            let table = crate::post::mesh_gallery::run_gallery(&ctx)?;
            print!("{table}");
            println!("wrote {}", ctx.out_dir.display());
            Ok(())
        }
        PostCommand::Stones { dir, library } => {
            print!(
                "{}",
                crate::geometry::stone_family_report(&dir, library.as_deref())?
            );
            Ok(())
        }
    }
}
