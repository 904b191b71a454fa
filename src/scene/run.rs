//! The run contract shared by every solver binary:
//! `ballast-X SCENE.toml [--preset NAME] [--out DIR] [--threads N]`.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

use super::load::load_scene_with_overrides;
use super::validate::Validate;
use crate::{Error, Result};

/// The arguments every solver binary takes; flatten them into its clap parser with
/// `#[command(flatten)] run: RunArgs`.
#[derive(Clone, Debug, clap::Args)]
pub struct RunArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Preset to apply: a `[preset.NAME]` table of the scene file (e.g. quick, paper).
    #[arg(long, value_name = "NAME")]
    pub preset: Option<String>,
    /// Output directory [default: `results/<scene>[-<preset>]`].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Worker threads [default: all cores].
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Override a scene value after the preset, e.g. `--set qdem.dt_factor=0.5`
    /// (repeatable; VALUE is TOML, or a string).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

impl RunArgs {
    /// Checks the arguments and resolves the defaults into a [`RunContext`].
    pub fn context(&self) -> Result<RunContext> {
        if self.threads == Some(0) {
            return Err(Error::Message(
                "--threads: must be at least 1, got 0".to_string(),
            ));
        }
        if let Some(preset) = &self.preset {
            if preset.is_empty() || preset.contains(['/', '\\']) {
                return Err(Error::Message(format!(
                    "--preset: \"{preset}\" is not a preset name"
                )));
            }
        }
        let scene_name = self
            .scene
            .file_stem()
            .and_then(|stem| stem.to_str())
            .filter(|stem| !stem.is_empty())
            .ok_or_else(|| {
                Error::Message(format!(
                    "{}: not a scene file name (expected NAME.toml)",
                    self.scene.display()
                ))
            })?
            .to_string();
        let out_dir = self
            .out
            .clone()
            .unwrap_or_else(|| default_out_dir(&scene_name, self.preset.as_deref()));
        Ok(RunContext {
            scene_path: self.scene.clone(),
            scene_name,
            preset: self.preset.clone(),
            out_dir,
            threads: self.threads,
            overrides: self.set.clone(),
        })
    }
}

impl RunArgs {
    /// [`Self::context`] for a run that may resume (`--resume DIR`): the context writes
    /// to DIR (a run resumes in its own directory; an `--out` elsewhere is an error),
    /// and the flag says whether to resume.
    pub fn resumable_context(&self, resume: Option<&Path>) -> Result<(RunContext, bool)> {
        let mut ctx = self.context()?;
        let Some(dir) = resume else {
            return Ok((ctx, false));
        };
        if let Some(out) = self.out.as_ref().filter(|out| out.as_path() != dir) {
            return Err(Error::Message(format!(
                "--resume {} and --out {}: a run resumes in its own directory",
                dir.display(),
                out.display()
            )));
        }
        ctx.out_dir = dir.to_path_buf();
        Ok((ctx, true))
    }
}

/// `results/<scene>` or `results/<scene>-<preset>`, relative to the working directory.
pub fn default_out_dir(scene_name: &str, preset: Option<&str>) -> PathBuf {
    let dir = match preset {
        Some(preset) => format!("{scene_name}-{preset}"),
        None => scene_name.to_string(),
    };
    Path::new("results").join(dir)
}

/// A resolved run: which scene, which preset, where results go, how many threads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunContext {
    /// The scene file as given.
    pub scene_path: PathBuf,
    /// The scene's name: the file stem (`cantilever` for `scenes/cantilever.toml`).
    pub scene_name: String,
    /// The preset applied, if any.
    pub preset: Option<String>,
    /// Where the results go.
    pub out_dir: PathBuf,
    /// Requested worker threads (at least 1); `None` lets rayon use all cores.
    pub threads: Option<usize>,
    /// `--set KEY=VALUE` overrides applied after the preset.
    pub overrides: Vec<String>,
}

impl RunContext {
    /// Loads and validates the scene with this run's preset; also returns the merged
    /// TOML for the summary's `inputs`.
    pub fn load_scene<T: DeserializeOwned + Validate>(&self) -> Result<(T, toml::Table)> {
        load_scene_with_overrides(&self.scene_path, self.preset.as_deref(), &self.overrides)
    }

    /// Sizes the pool ([`Self::configure_threads`]) and runs `f` on one of its worker
    /// threads. The NSCD solvers start several parallel loops per NLGS iteration; from
    /// the main thread each would be injected into the pool and the main thread put
    /// to sleep until it ends (a futex round trip per loop: a fifth of the quick bed's
    /// wall time went to the kernel on one thread), while from a worker the loop just
    /// runs.
    pub fn run_on_pool<R: Send>(&self, f: impl FnOnce(&RunContext) -> R + Send) -> Result<R> {
        self.configure_threads()?;
        Ok(rayon::scope(|_| f(self)))
    }

    /// Sizes rayon's global pool to the requested thread count and returns the number
    /// of threads the run will use. Calling it again with the same count is fine; a
    /// different count after the pool exists is an error.
    pub fn configure_threads(&self) -> Result<usize> {
        let Some(threads) = self.threads else {
            return Ok(rayon::current_num_threads());
        };
        if threads == 0 {
            return Err(Error::Message(
                "--threads: must be at least 1, got 0".to_string(),
            ));
        }
        match rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
        {
            Ok(()) => Ok(threads),
            Err(_) if rayon::current_num_threads() == threads => Ok(threads),
            Err(err) => Err(Error::Message(format!(
                "--threads {threads}: the thread pool already runs {} threads ({err})",
                rayon::current_num_threads()
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        run: RunArgs,
    }

    #[test]
    fn clap_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    #[test]
    fn defaults_and_overrides() {
        let cli = Cli::try_parse_from(["x", "scenes/cantilever.toml"]).unwrap();
        let ctx = cli.run.context().unwrap();
        assert_eq!(ctx.scene_name, "cantilever");
        assert_eq!(ctx.out_dir, Path::new("results/cantilever"));
        assert_eq!(ctx.threads, None);

        let cli = Cli::try_parse_from([
            "x",
            "scenes/cantilever.toml",
            "--preset",
            "quick",
            "--threads",
            "2",
        ])
        .unwrap();
        let ctx = cli.run.context().unwrap();
        assert_eq!(ctx.preset.as_deref(), Some("quick"));
        assert_eq!(ctx.out_dir, Path::new("results/cantilever-quick"));
        assert_eq!(ctx.threads, Some(2));

        let cli =
            Cli::try_parse_from(["x", "a.toml", "--out", "/tmp/r", "--preset", "paper"]).unwrap();
        assert_eq!(cli.run.context().unwrap().out_dir, Path::new("/tmp/r"));
    }

    #[test]
    fn bad_arguments_are_errors() {
        let cli = Cli::try_parse_from(["x", "a.toml", "--threads", "0"]).unwrap();
        assert_eq!(
            cli.run.context().unwrap_err().to_string(),
            "--threads: must be at least 1, got 0"
        );
        assert!(Cli::try_parse_from(["x", "a.toml", "--threads", "-1"]).is_err());
        assert!(Cli::try_parse_from(["x"]).is_err());
        let cli = Cli::try_parse_from(["x", "a.toml", "--preset", "../x"]).unwrap();
        assert!(cli.run.context().is_err());
        let ctx = RunContext {
            scene_path: "a.toml".into(),
            scene_name: "a".into(),
            preset: None,
            out_dir: "o".into(),
            threads: Some(0),
            overrides: Vec::new(),
        };
        assert!(ctx.configure_threads().is_err());
    }
}
