//! `ballast-post track-compare`: several track runs of the same loads side by side —
//! what each cost and how far its sleeper spectrum is from a reference run's (seed
//! 004 §4's all-deformable model, or any run chosen), and its settlement.
//!
//! It answers the two questions of the rigid/deformable choice and of the friction
//! study:
//! - accuracy against wall time: the relative L2 difference of one sensor's smoothed
//!   acceleration spectrum (Parzen, 20 Hz, 0 < f ≤ 1 kHz) from the reference's,
//!   ‖A − A_ref‖₂ / ‖A_ref‖₂ over the bins, against the wall time of the time loop;
//! - settlement per run, e.g. µ = 0.577 against µ = 1.73 (seed 004 §4.1): the
//!   sleeper's (its bottom face, from the end of settling), and the stone sensors'
//!   (B*: mean final vertical displacement, and their largest lateral one).
//!
//! Also the sleeper's settlement passage by passage of the load (bogie by bogie,
//! [`super::track_passages`]).
//!
//! Reads each directory's `summary.json`, `sensors.csv` and `track.csv` (as
//! `ballast-qdem` writes them); writes `PREFIX.md` (the tables), `PREFIX.json`, the
//! chart `PREFIX.svg/.png` and the runs' displacement histories on one chart,
//! `PREFIX_histories.svg/.png` (seed 004 Figure 8 with every run on it).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use serde_json::{json, Value};

use super::chart::{write_svg_png, Figure, LinePanel, Stacked, PALETTE};
use super::track_charts::decimate;
use super::track_passages::{read_passages, Passage};
use super::track_sensors::read_sensors;
use super::track_spectra::{smoothed_spectrum, with_suffix};
use crate::{Error, Result};

/// How the comparison is made.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// The sensor whose vertical acceleration spectrum is compared (S2: mid-sleeper).
    pub sensor: String,
    /// Parzen bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Highest frequency compared, Hz.
    pub max_hz: f64,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            sensor: "S2".into(),
            bandwidth_hz: 20.0,
            max_hz: 1000.0,
        }
    }
}

/// One run of the comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct ComparedRun {
    /// The run's directory.
    pub dir: PathBuf,
    /// What distinguishes it: the stone model and the ballast friction.
    pub label: String,
    /// Stones modelled as QDEM bodies, and in all.
    pub deformable_stones: u64,
    /// Stones in the bed.
    pub stones: u64,
    /// Ballast–ballast friction coefficient.
    pub friction: f64,
    /// Wall time of the time loop (s).
    pub wall_s: f64,
    /// Simulated seconds per wall hour.
    pub simulated_s_per_wall_hour: f64,
    /// Touching contact pairs per second of wall time.
    pub contact_pairs_per_s: f64,
    /// Peak resident memory (MiB).
    pub peak_memory_mib: f64,
    /// Sleeper settlement since the end of settling (m; negative: down).
    pub settlement_m: f64,
    /// Mean final vertical displacement of the stone sensors B* (m; negative: down):
    /// the ballast settlement of seed 004 Figure 8b.
    pub stone_settlement_m: f64,
    /// Largest lateral (y) displacement magnitude of a stone sensor over the record
    /// (m): seed 004 Figure 8a.
    pub stone_lateral_m: f64,
    /// Relative L2 difference of the sensor's spectrum from the reference's.
    pub spectrum_difference: f64,
    /// The sleeper's settlement passage by passage (bogie by bogie), from `track.csv`.
    pub passages: Vec<Passage>,
}

fn figure(summary: &Value, path: &Path, key: &str) -> Result<f64> {
    summary["figures"][key]
        .as_f64()
        .ok_or_else(|| Error::invalid(path, format!("figures.{key}: missing or not a number")))
}

/// What a run's `sensors.csv` gives: the smoothed vertical acceleration spectrum of
/// the compared sensor over 0 < f ≤ max_hz, and the stone sensors' settlement and
/// largest lateral displacement (NaN without stone sensors).
struct SensorFigures {
    frequencies_hz: Vec<f64>,
    amplitudes: Vec<f64>,
    stone_settlement_m: f64,
    stone_lateral_m: f64,
}

fn sensor_figures(dir: &Path, options: &CompareOptions) -> Result<SensorFigures> {
    let path = dir.join("sensors.csv");
    let record = read_sensors(&path)?;
    let stones: Vec<_> = record
        .sensors
        .iter()
        .filter(|s| s.name.starts_with('B'))
        .collect();
    let (stone_settlement_m, stone_lateral_m) = if stones.is_empty() {
        (f64::NAN, f64::NAN)
    } else {
        let last = |v: &[f64]| v.last().copied().unwrap_or(0.0);
        (
            stones
                .iter()
                .map(|s| last(&s.displacement_m[2]))
                .sum::<f64>()
                / stones.len() as f64,
            stones
                .iter()
                .flat_map(|s| s.displacement_m[1].iter())
                .fold(0.0, |m: f64, y| m.max(y.abs())),
        )
    };
    let sensor = record
        .sensors
        .iter()
        .find(|s| s.name == options.sensor)
        .ok_or_else(|| {
            Error::invalid(
                &path,
                format!(
                    "no sensor \"{}\" (columns {}_az_m_per_s2)",
                    options.sensor, options.sensor
                ),
            )
        })?;
    let s = smoothed_spectrum(
        &sensor.acceleration_m_per_s2[2],
        record.dt_s,
        options.bandwidth_hz,
    )?;
    let keep: Vec<usize> = (0..s.frequencies_hz.len())
        .filter(|&i| s.frequencies_hz[i] > 0.0 && s.frequencies_hz[i] <= options.max_hz)
        .collect();
    Ok(SensorFigures {
        frequencies_hz: keep.iter().map(|&i| s.frequencies_hz[i]).collect(),
        amplitudes: keep.iter().map(|&i| s.amplitudes[i]).collect(),
        stone_settlement_m,
        stone_lateral_m,
    })
}

fn label(summary: &Value) -> String {
    let track = &summary["inputs"]["track"];
    let stones = track["stones"].as_str().unwrap_or("rigid");
    let model = match stones {
        "near" => format!(
            "near ({})",
            track["deformable_within"].as_str().unwrap_or("default")
        ),
        other => other.to_string(),
    };
    let mu = &summary["inputs"]["friction"]["ballast_ballast"];
    match mu.as_f64() {
        Some(mu) => format!("{model}, µ {mu}"),
        None => model,
    }
}

/// Compares the runs in `dirs` with the run in `reference` (which may be one of them).
pub fn compare(
    dirs: &[PathBuf],
    reference: &Path,
    options: &CompareOptions,
) -> Result<Vec<ComparedRun>> {
    let reference_figures = sensor_figures(reference, options)?;
    let (ref_f, ref_a) = (
        &reference_figures.frequencies_hz,
        &reference_figures.amplitudes,
    );
    let ref_norm = ref_a.iter().map(|a| a * a).sum::<f64>().sqrt();
    dirs.iter()
        .map(|dir| {
            let path = dir.join("summary.json");
            let summary = super::read_json(&path)?;
            let figures = sensor_figures(dir, options)?;
            let (f, a) = (&figures.frequencies_hz, &figures.amplitudes);
            if f != ref_f {
                return Err(Error::invalid(
                    dir.join("sensors.csv"),
                    format!(
                        "{} spectrum bins up to {} Hz, the reference {} has {}: the records \
                         differ in length or rate",
                        f.len(),
                        options.max_hz,
                        reference.display(),
                        ref_f.len()
                    ),
                ));
            }
            let diff = a
                .iter()
                .zip(ref_a)
                .map(|(a, r)| (a - r) * (a - r))
                .sum::<f64>()
                .sqrt();
            let wall = summary["wall_time_s"]["stepping"].as_f64().ok_or_else(|| {
                Error::invalid(&path, "wall_time_s.stepping: missing or not a number")
            })?;
            let passages = read_passages(&dir.join("track.csv"))?;
            Ok(ComparedRun {
                passages,
                dir: dir.clone(),
                label: label(&summary),
                deformable_stones: figure(&summary, &path, "deformable_stones")? as u64,
                stones: figure(&summary, &path, "stones")? as u64,
                friction: summary["inputs"]["friction"]["ballast_ballast"]
                    .as_f64()
                    .unwrap_or(f64::NAN),
                wall_s: wall,
                simulated_s_per_wall_hour: figure(&summary, &path, "simulated_s_per_wall_hour")?,
                contact_pairs_per_s: figure(&summary, &path, "contact_pairs_per_s")?,
                peak_memory_mib: figure(&summary, &path, "peak_memory_mib")?,
                settlement_m: figure(&summary, &path, "sleeper_settlement_m")?,
                stone_settlement_m: figures.stone_settlement_m,
                stone_lateral_m: figures.stone_lateral_m,
                // A record too short for any spectrum in the band (both zero) is no
                // difference; a signal against a silent reference has no ratio.
                spectrum_difference: if ref_norm > 0.0 {
                    diff / ref_norm
                } else if diff == 0.0 {
                    0.0
                } else {
                    f64::NAN
                },
            })
        })
        .collect()
}

/// The markdown table of `runs`.
pub fn table(runs: &[ComparedRun], reference: &Path, options: &CompareOptions) -> String {
    let mut s = format!(
        "Reference: {} · {} vertical acceleration, Parzen {} Hz, 0–{} Hz\n\n",
        reference.display(),
        options.sensor,
        options.bandwidth_hz,
        options.max_hz
    );
    s.push_str(
        "| run | deformable / stones | wall s | simulated s / wall h | contact pairs/s | \
         memory MiB | sleeper settlement µm | stone settlement µm | stone lateral µm | \
         spectrum difference |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in runs {
        let _ = writeln!(
            s,
            "| {} | {} / {} | {:.1} | {:.3} | {:.3e} | {:.0} | {:.3} | {:.4} | {:.4} | {} |",
            r.label,
            r.deformable_stones,
            r.stones,
            r.wall_s,
            r.simulated_s_per_wall_hour,
            r.contact_pairs_per_s,
            r.peak_memory_mib,
            r.settlement_m * 1e6,
            r.stone_settlement_m * 1e6,
            r.stone_lateral_m * 1e6,
            if r.spectrum_difference.is_nan() {
                "no ratio (silent reference)".to_string()
            } else {
                format!("{:.2} %", 100.0 * r.spectrum_difference)
            }
        );
    }
    s.push_str(&passage_table(runs));
    s
}

/// The sleeper's settlement per passage of the load (a bogie, or axles close together;
/// [`read_passages`]), a column per run, the passages' times from the first run.
fn passage_table(runs: &[ComparedRun]) -> String {
    let count = runs.iter().map(|r| r.passages.len()).max().unwrap_or(0);
    if count == 0 {
        return String::new();
    }
    let mut s = String::from(
        "\nSleeper settlement per passage of the load (µm; the record cut midway between \
         passages, so they add up to the whole):\n\n| passage | load above 10 % of its peak |",
    );
    for r in runs {
        let _ = write!(s, " {} |", r.label);
    }
    s.push_str("\n|---|---|");
    s.push_str(&"---:|".repeat(runs.len()));
    s.push('\n');
    for k in 0..count {
        let when = runs
            .iter()
            .find_map(|r| r.passages.get(k))
            .map_or(String::new(), |p| {
                format!("{:.3}–{:.3} s", p.load_from_s, p.load_to_s)
            });
        let _ = write!(s, "| {} | {when} |", k + 1);
        for r in runs {
            match r.passages.get(k) {
                Some(p) => {
                    let _ = write!(s, " {:.1} |", 1e6 * p.settlement_m);
                }
                None => s.push_str(" — |"),
            }
        }
        s.push('\n');
    }
    s
}

/// Writes `PREFIX.md`, `PREFIX.json`, the chart `PREFIX.svg/.png` and the histories
/// `PREFIX_histories.svg/.png`; returns the paths.
pub fn write_report(
    runs: &[ComparedRun],
    reference: &Path,
    options: &CompareOptions,
    prefix: &Path,
) -> Result<Vec<PathBuf>> {
    // `with_suffix`, not `with_extension`: a prefix such as `runs/mu-0.577` keeps its
    // dot. `write_atomic` creates the missing directories.
    let md = with_suffix(prefix, ".md");
    crate::output::write_atomic(&md, table(runs, reference, options).as_bytes())?;
    let js = with_suffix(prefix, ".json");
    let value = json!({
        "reference": reference.display().to_string(),
        "sensor": options.sensor,
        "bandwidth_hz": options.bandwidth_hz,
        "max_hz": options.max_hz,
        "runs": runs.iter().map(|r| json!({
            "dir": r.dir.display().to_string(),
            "label": r.label,
            "deformable_stones": r.deformable_stones,
            "stones": r.stones,
            "friction": r.friction,
            "wall_s": r.wall_s,
            "simulated_s_per_wall_hour": r.simulated_s_per_wall_hour,
            "contact_pairs_per_s": r.contact_pairs_per_s,
            "peak_memory_mib": r.peak_memory_mib,
            "sleeper_settlement_m": r.settlement_m,
            "stone_settlement_m": r.stone_settlement_m,
            "stone_lateral_m": r.stone_lateral_m,
            "spectrum_difference": r.spectrum_difference,
            "passages": r.passages,
        })).collect::<Vec<_>>(),
    });
    crate::output::write_json(&js, &value)?;
    let mut paths = vec![md, js];
    paths.extend(write_svg_png(
        &CompareChart(runs),
        &with_suffix(prefix, ".svg"),
        (1000, 700),
    )?);
    let panels = history_panels(runs, options)?;
    let height = 330 * panels.len() as u32;
    paths.extend(write_svg_png(
        &Stacked(panels),
        &with_suffix(prefix, "_histories.svg"),
        (1100, height),
    )?);
    Ok(paths)
}

/// The runs' displacement histories, a line per run and sensor: the compared sensor's
/// vertical displacement (the sleeper's settlement, at S2 by default), then the stone
/// sensors' (B*) vertical and lateral ones (seed 004 Figure 8b and 8a), in mm.
fn history_panels(
    runs: &[ComparedRun],
    options: &CompareOptions,
) -> Result<Vec<LinePanel<'static>>> {
    let (mut sleeper, mut vertical, mut lateral) = (Vec::new(), Vec::new(), Vec::new());
    for r in runs {
        let record = read_sensors(&r.dir.join("sensors.csv"))?;
        let t = &record.time_s;
        for s in &record.sensors {
            let name = format!("{}: {}", r.label, s.name);
            let line = |axis: usize| decimate(t, &s.displacement_m[axis], 1e3, 1500);
            if s.name == options.sensor {
                sleeper.push((name.clone(), line(2)));
            }
            if s.name.starts_with('B') {
                vertical.push((name.clone(), line(2)));
                lateral.push((name, line(1)));
            }
        }
    }
    let panel = |title: String, y_desc: &'static str, series| LinePanel {
        title,
        x_desc: "time (s)",
        y_desc,
        log10_y: false,
        series,
        shade_x: None,
    };
    let mut panels = vec![panel(
        format!(
            "{} vertical displacement (settlement negative)",
            options.sensor
        ),
        "uz (mm)",
        sleeper,
    )];
    if !vertical.is_empty() {
        panels.push(panel(
            "stone sensors' vertical displacement".into(),
            "uz (mm)",
            vertical,
        ));
        panels.push(panel(
            "stone sensors' lateral displacement".into(),
            "uy (mm)",
            lateral,
        ));
    }
    Ok(panels)
}

struct CompareChart<'a>(&'a [ComparedRun]);

impl Figure for CompareChart<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> std::result::Result<(), String> {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let runs = self.0;
        let walls: Vec<f64> = runs.iter().map(|r| r.wall_s.max(1e-3)).collect();
        let x0 = walls.iter().copied().fold(f64::INFINITY, f64::min) / 1.5;
        let x1 = walls.iter().copied().fold(0.0, f64::max) * 1.5;
        let y1 = runs
            .iter()
            .map(|r| 100.0 * r.spectrum_difference)
            .filter(|d| d.is_finite())
            .fold(1.0, f64::max)
            * 1.2;
        let mut chart = ChartBuilder::on(root)
            .caption(
                "sleeper spectrum difference from the reference vs wall time",
                ("sans-serif", 22),
            )
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(65)
            .build_cartesian_2d((x0..x1).log_scale(), 0.0..y1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("wall time of the time loop (s)")
            .y_desc("spectrum difference (%)")
            .x_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(err)?;
        for (i, (r, &x)) in runs.iter().zip(&walls).enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let y = 100.0 * r.spectrum_difference;
            if !y.is_finite() {
                continue;
            }
            chart
                .draw_series(std::iter::once(Circle::new((x, y), 7, colour.filled())))
                .map_err(err)?
                .label(r.label.clone())
                .legend(move |(lx, ly)| Circle::new((lx + 10, ly), 6, colour.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(err)?;
        Ok(())
    }
}
