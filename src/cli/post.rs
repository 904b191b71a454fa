//! `ballast-post`: reports and charts from meshes and results.

use crate::post::track_compare;
use crate::post::track_sensors::{self, Component};
use crate::post::track_spectra::{self, SpectraOptions};
use crate::post::train_load::{self, TrainSpec};
use crate::scene::RunArgs;
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

/// `ballast-post`: post-processing of meshes and results.
#[derive(Debug, Parser)]
#[command(
    name = "ballast-post",
    version,
    about = "Post-processing: mesh gallery (VTK + quality table), stone-family statistics \
             against the real grain library, speed/accuracy chart, train loads and track \
             spectra, compactness of a packed bed by control box and depth"
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
    /// Rail-seat loads of a passing train (CSV time_s,Rp1,Rp2 in N) for the track scene:
    /// Zimmermann influence line of each wheel plus seeded roughness noise (seed 004 §4).
    TrainLoad(TrainLoadArgs),
    /// Track runs of the same loads side by side: wall time, throughput, memory,
    /// settlement, and each run's sleeper spectrum difference from a reference run
    /// (charted against wall time: the rigid/deformable choice; the friction study).
    TrackCompare {
        /// Run directories of ballast-qdem track scenes (summary.json, sensors.csv).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// The reference run (e.g. all stones deformable) [default: the first DIR].
        #[arg(long)]
        reference: Option<PathBuf>,
        /// Sensor whose vertical acceleration spectrum is compared.
        #[arg(long, default_value = "S2")]
        sensor: String,
        /// Parzen smoothing bandwidth, Hz.
        #[arg(long, default_value_t = 20.0)]
        bandwidth_hz: f64,
        /// Highest frequency compared, Hz.
        #[arg(long, default_value_t = 1000.0)]
        max_hz: f64,
        /// Output prefix: PREFIX.md, PREFIX.json, PREFIX.svg, PREFIX.png.
        #[arg(long)]
        out: PathBuf,
    },
    /// Parzen-smoothed spectra, peaks and mobility of track sensors, with displacement and
    /// acceleration histories (seed 004 Figures 8-12).
    Spectra {
        /// Sensor CSV: time_s, then NAME_ux_m … NAME_az_m_per_s2 for each sensor.
        sensors: PathBuf,
        /// Output prefix: PREFIX_spectra.csv/.svg/.png, PREFIX_histories.svg/.png, PREFIX.json.
        #[arg(long)]
        out: PathBuf,
        /// Rail-seat load CSV (time_s,Rp1,Rp2): adds load spectra and the mobility.
        #[arg(long)]
        load: Option<PathBuf>,
        /// Window start, s (default: the first sample).
        #[arg(long, allow_negative_numbers = true)]
        from: Option<f64>,
        /// Window end, s, exclusive (default: the end of the record).
        #[arg(long, allow_negative_numbers = true)]
        to: Option<f64>,
        /// Parzen smoothing bandwidth, Hz.
        #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
        bandwidth_hz: f64,
        /// Highest frequency written, charted and searched for peaks, Hz.
        #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
        max_hz: f64,
        /// Component of acceleration and velocity analysed.
        #[arg(long, value_enum, default_value_t = Component::Z)]
        component: Component,
        /// Peaks kept per sensor.
        #[arg(long, default_value_t = 5)]
        peaks: usize,
    },
    /// Compactness of a ballast-pack bed measured again from its packing file, in the
    /// control boxes of its summary and by depth below each box's top (the loose band
    /// under a sleeper's underside apart from the bulk below it).
    Compactness {
        /// Bed directory of ballast-pack (packing.toml, summary.json).
        dir: PathBuf,
        /// Slice height of the profiles, m [default: a quarter of the bed's d50].
        #[arg(long, allow_negative_numbers = true)]
        slice: Option<f64>,
        /// Output prefix: PREFIX.md, PREFIX.json, PREFIX.svg, PREFIX.png [default:
        /// DIR/compactness].
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

/// Declares [`TrainLoadArgs`] with one optional flag per [`TrainSpec`] field (same name,
/// dashes for underscores) and the code that lays the given ones over a spec.
macro_rules! train_load_args {
    ($($field:ident: $ty:ty, $help:literal;)*) => {
        /// `ballast-post train-load`: the output, an optional TOML spec and one flag per
        /// [`TrainSpec`] field that overrides the spec (defaults: [`TrainSpec::default`]).
        #[derive(Debug, clap::Args)]
        pub struct TrainLoadArgs {
            /// Output CSV (time_s,Rp1,Rp2).
            #[arg(long)]
            out: PathBuf,
            /// TOML file of TrainSpec fields (cars, speed_km_h, …); flags override it.
            #[arg(long)]
            spec: Option<PathBuf>,
            $(
                #[doc = $help]
                #[arg(long, allow_negative_numbers = true)]
                $field: Option<$ty>,
            )*
        }

        impl TrainLoadArgs {
            fn apply(&self, spec: &mut TrainSpec) {
                $( if let Some(value) = self.$field { spec.$field = value.into(); } )*
            }

            fn given(&self, field: &str) -> bool {
                $( (field == stringify!($field) && self.$field.is_some()) || )* false
            }
        }
    };
}

train_load_args! {
    cars: usize, "Number of cars [default 5, seed 004 Fig. 5].";
    car_length_m: f64, "Car length, m [default 20].";
    bogie_centres_m: f64, "Distance between bogie centres, m [default 13.8].";
    axle_base_m: f64, "Axle base of a bogie, m [default 2.1].";
    speed_km_h: f64, "Train speed, km/h [default 115].";
    axle_load_kn: f64, "Static axle load, kN [default 120].";
    sleeper_spacing_m: f64, "Sleeper spacing, m [default 0.6].";
    characteristic_length_m: f64, "Characteristic length of the rail on its support, m [default 0.8].";
    lead_in_m: f64, "Distance of the first axle before the sleeper at t = 0, m [default 4.4, a zero of the influence line].";
    lead_out_m: f64, "Distance of the last axle past the sleeper at the end, m [default 8].";
    duration_s: f64, "Record length, s [default: until the last axle is lead-out past].";
    sample_rate_hz: f64, "Sampling rate, Hz [default 10000].";
    roughness_fraction: f64, "Roughness RMS as a fraction of the quasi-static load; 0 = off [default 0.2].";
    roughness_low_hz: f64, "Lower edge of the roughness band, Hz [default 50].";
    roughness_high_hz: f64, "Upper edge of the roughness band, Hz [default 1500].";
    imbalance: f64, "Rp1 × (1 + imbalance), Rp2 × (1 − imbalance) [default 0].";
    seed: u64, "Seed of the roughness noise [default 1].";
}

fn run_train_load(args: &TrainLoadArgs) -> crate::Result<()> {
    let mut spec = match &args.spec {
        Some(path) => read_train_spec(path)?,
        None => TrainSpec::default(),
    };
    args.apply(&mut spec);
    if let Err(bad) = spec.validate() {
        let flag = format!("--{}", bad.field.replace('_', "-"));
        let origin = match &args.spec {
            Some(path) if !args.given(bad.field) => {
                format!("{} (key {} of {})", flag, bad.field, path.display())
            }
            _ => flag,
        };
        return Err(crate::Error::Message(format!(
            "train-load: {origin} {}",
            bad.reason
        )));
    }
    let load = train_load::train_load(&spec)?;
    load.write_csv(&args.out)?;
    let (p1, p2) = load.peaks_n();
    let n = load.time_s.len();
    println!(
        "wrote {}: {n} rows, 0–{} s at {} Hz, {} axles at {} km/h, peak Rp1 = {:.2} kN, Rp2 = {:.2} kN",
        args.out.display(),
        load.time_s[n - 1],
        spec.sample_rate_hz,
        spec.axle_offsets_m().len(),
        spec.speed_km_h,
        p1 / 1e3,
        p2 / 1e3
    );
    Ok(())
}

fn read_train_spec(path: &Path) -> crate::Result<TrainSpec> {
    let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io(path, e))?;
    let table = crate::scene::parse_table(path, &text)?;
    crate::scene::deserialize_table(&table).map_err(|what| crate::Error::invalid(path, what))
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
        PostCommand::TrainLoad(args) => run_train_load(&args),
        PostCommand::TrackCompare {
            dirs,
            reference,
            sensor,
            bandwidth_hz,
            max_hz,
            out,
        } => {
            let options = track_compare::CompareOptions {
                sensor,
                bandwidth_hz,
                max_hz,
            };
            let reference = reference.unwrap_or_else(|| dirs[0].clone());
            let runs = track_compare::compare(&dirs, &reference, &options)?;
            print!("{}", track_compare::table(&runs, &reference, &options));
            for file in track_compare::write_report(&runs, &reference, &options, &out)? {
                println!("wrote {}", file.display());
            }
            Ok(())
        }
        PostCommand::Spectra {
            sensors,
            out,
            load,
            from,
            to,
            bandwidth_hz,
            max_hz,
            component,
            peaks,
        } => {
            let record = track_sensors::read_sensors(&sensors)?;
            let load = load.as_deref().map(track_sensors::read_load).transpose()?;
            let options = SpectraOptions {
                from_s: from,
                to_s: to,
                bandwidth_hz,
                max_hz,
                component,
                peak_count: peaks,
            };
            let spectra = track_spectra::analyse(&record, load.as_ref(), &options)?;
            let files = track_spectra::write_report(&record, &spectra, &out)?;
            print!("{}", spectra.peak_table());
            for file in files {
                println!("wrote {}", file.display());
            }
            Ok(())
        }
        PostCommand::Compactness { dir, slice, out } => {
            let report = crate::post::compactness::analyse(&dir, slice)?;
            print!("{}", report.table());
            let out = out.unwrap_or_else(|| dir.join("compactness"));
            for file in crate::post::compactness::write_report(&report, &out)? {
                println!("wrote {}", file.display());
            }
            Ok(())
        }
    }
}
