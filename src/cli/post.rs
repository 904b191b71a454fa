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
    /// Speed/accuracy chart of the cantilever from ballast-qdem and ballast-fem results:
    /// error against wall time and mesh size (SVG, PNG and a markdown table).
    SpeedAccuracy {
        /// Directories searched (recursively) for summary.json files.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output prefix: writes PREFIX.svg, PREFIX.png and PREFIX.md.
        #[arg(long)]
        out: PathBuf,
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
        PostCommand::SpeedAccuracy { dirs, out } => {
            use crate::post::speed_accuracy::{collect, draw, table};
            let points = collect(&dirs)?;
            if points.is_empty() {
                return Err(crate::Error::Message(format!(
                    "speed-accuracy: no cantilever summary.json from ballast-qdem or ballast-fem under {}",
                    dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
                )));
            }
            if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).map_err(|e| crate::Error::io(dir, e))?;
            }
            let text = table(&points);
            crate::output::write_atomic(out.with_extension("md"), text.as_bytes())?;
            print!("{text}");
            for file in draw(&points, &out)? {
                println!("wrote {}", file.display());
            }
            Ok(())
        }
    }
}
