//! The speed/accuracy chart of the cantilever (seed 004 §3.1): error in the tip
//! deflection and in the first frequency against wall time and against mesh size, for
//! QDEM (over mesh size × time-step factor) and for the reference FEM (over mesh size),
//! from the `summary.json` files that `ballast-qdem` and `ballast-fem` wrote.
//!
//! The reference value of each quantity is the FEM result Richardson-extrapolated from
//! the two finest FEM meshes with order 2 (linear tetra converge as h² in displacement
//! and frequency), or the finest FEM value when there is only one. Mesh size is the
//! edge of the regular tetrahedron of the mean element volume, h = (6√2 V / n)^{1/3}.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use serde_json::Value;

use super::chart::{write_svg_png, Figure, PALETTE};
use crate::scene::Density;
use crate::{Error, Result};

/// Which solver produced a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// ballast-qdem (explicit, lumped mass).
    Qdem,
    /// ballast-fem (implicit static / consistent-mass modes).
    Fem,
}

/// Which figure a point is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// `tip_deflection_m`.
    Deflection,
    /// `first_frequency_hz`.
    Frequency,
}

impl Quantity {
    fn label(self) -> &'static str {
        match self {
            Quantity::Deflection => "tip deflection",
            Quantity::Frequency => "first frequency",
        }
    }
}

/// One run on the chart.
#[derive(Debug, Clone)]
pub struct RunPoint {
    /// Solver.
    pub method: Method,
    /// Figure.
    pub quantity: Quantity,
    /// Its value (m or Hz).
    pub value: f64,
    /// Total wall time of the run (s), all phases.
    pub wall_s: f64,
    /// Tetra in the mesh.
    pub tetra: u64,
    /// Equivalent mesh size (m).
    pub h_m: f64,
    /// QDEM: dt / stable dt.
    pub dt_factor: Option<f64>,
    /// The summary file.
    pub source: PathBuf,
}

/// Every cantilever summary under `dirs` (searched recursively).
pub fn collect(dirs: &[PathBuf]) -> Result<Vec<RunPoint>> {
    let mut files = Vec::new();
    for dir in dirs {
        find_summaries(dir, &mut files)?;
    }
    files.sort();
    let mut points = Vec::new();
    for file in files {
        let summary = super::read_json(&file)?;
        if let Some(p) = point(&file, &summary)? {
            points.push(p);
        }
    }
    Ok(points)
}

fn find_summaries(dir: &Path, files: &mut Vec<PathBuf>) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.is_dir() {
            find_summaries(&path, files)?;
        } else if path.file_name().is_some_and(|n| n == "summary.json") {
            files.push(path);
        }
    }
    Ok(())
}

fn point(file: &Path, s: &Value) -> Result<Option<RunPoint>> {
    let scene = s["scene"].as_str().unwrap_or("");
    if !scene.starts_with("cantilever") {
        return Ok(None);
    }
    let fig = &s["figures"];
    let method = if fig["stable_dt_s"].is_number() {
        Method::Qdem
    } else if fig["command"].is_string() {
        Method::Fem
    } else {
        return Ok(None);
    };
    let wall_s: f64 = s["wall_time_s"]
        .as_object()
        .map_or(0.0, |m| m.values().filter_map(Value::as_f64).sum());
    let tetra = fig["tetra"].as_u64().unwrap_or(0);
    let volume = match fig["volume_m3"].as_f64() {
        Some(v) => v,
        None => {
            let mass = fig["mass_kg"].as_f64();
            let density = s["inputs"]["material"]["density"]
                .as_str()
                .and_then(|d| Density::parse(d).ok())
                .map(|d| d.si())
                .or_else(|| s["inputs"]["material"]["density"].as_f64());
            match (mass, density) {
                (Some(m), Some(rho)) => m / rho,
                _ => {
                    return Err(Error::invalid(
                        file,
                        "no figures.volume_m3 (or mass_kg and inputs.material.density)",
                    ))
                }
            }
        }
    };
    if tetra == 0 {
        return Err(Error::invalid(file, "figures.tetra is missing or zero"));
    }
    let h_m = (6.0 * 2f64.sqrt() * volume / tetra as f64).cbrt();
    let dt_factor = match (fig["dt_s"].as_f64(), fig["stable_dt_s"].as_f64()) {
        (Some(dt), Some(stable)) => Some(dt / stable),
        _ => None,
    };
    let frequency = fig["first_frequency_hz"].as_f64();
    // ballast-fem modes also lists frequencies; a QDEM vibration run has the frequency;
    // static runs have the deflection.
    let (quantity, value) = if let Some(d) = fig["tip_deflection_m"].as_f64() {
        (Quantity::Deflection, d)
    } else if let Some(f) = frequency {
        (Quantity::Frequency, f)
    } else {
        return Ok(None);
    };
    Ok(Some(RunPoint {
        method,
        quantity,
        value,
        wall_s,
        tetra,
        h_m,
        dt_factor,
        source: file.to_path_buf(),
    }))
}

/// The reference value of `quantity` and how it was obtained.
pub fn reference(points: &[RunPoint], quantity: Quantity) -> Option<(f64, String)> {
    let mut fem: Vec<&RunPoint> = points
        .iter()
        .filter(|p| p.method == Method::Fem && p.quantity == quantity)
        .collect();
    fem.sort_by(|a, b| a.h_m.total_cmp(&b.h_m));
    fem.dedup_by(|a, b| (a.h_m - b.h_m).abs() < 1e-12 * b.h_m);
    match fem.as_slice() {
        [] => None,
        [only] => Some((only.value, format!("FEM at h = {:.4} m", only.h_m))),
        [fine, coarse, ..] => {
            let r2 = (coarse.h_m / fine.h_m).powi(2);
            let extrapolated = fine.value + (fine.value - coarse.value) / (r2 - 1.0);
            Some((
                extrapolated,
                format!(
                    "FEM Richardson (order 2) from h = {:.4} and {:.4} m",
                    fine.h_m, coarse.h_m
                ),
            ))
        }
    }
}

/// Least-squares slope of log|error| against log h (the observed convergence order).
pub fn convergence_order(points: &[&RunPoint], reference: f64) -> Option<f64> {
    let xy: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| (p.value - reference).abs() > 0.0)
        .map(|p| (p.h_m.ln(), ((p.value - reference) / reference).abs().ln()))
        .collect();
    if xy.len() < 2 {
        return None;
    }
    let n = xy.len() as f64;
    let (mx, my) = (
        xy.iter().map(|p| p.0).sum::<f64>() / n,
        xy.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = xy.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = xy.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Series of one method (and QDEM time-step factor), sorted by mesh size.
fn series(points: &[RunPoint], quantity: Quantity) -> Vec<(String, Vec<&RunPoint>)> {
    let mut groups: Vec<(String, Vec<&RunPoint>)> = Vec::new();
    for p in points.iter().filter(|p| p.quantity == quantity) {
        let label = match (p.method, p.dt_factor) {
            (Method::Fem, _) => "FEM".to_string(),
            (Method::Qdem, Some(f)) => format!("QDEM dt = {f:.2} × stable"),
            (Method::Qdem, None) => "QDEM".to_string(),
        };
        match groups.iter_mut().find(|g| g.0 == label) {
            Some(g) => g.1.push(p),
            None => groups.push((label, vec![p])),
        }
    }
    for g in &mut groups {
        g.1.sort_by(|a, b| b.h_m.total_cmp(&a.h_m));
    }
    groups.sort_by(|a, b| a.0.cmp(&b.0));
    groups
}

/// The table of every point: method, h, tetra, value, error, wall time; and the orders.
pub fn table(points: &[RunPoint]) -> String {
    let mut out = String::new();
    for quantity in [Quantity::Deflection, Quantity::Frequency] {
        let Some((reference, how)) = reference(points, quantity) else {
            continue;
        };
        let unit = if quantity == Quantity::Deflection {
            "µm"
        } else {
            "Hz"
        };
        let scale = if quantity == Quantity::Deflection {
            1e6
        } else {
            1.0
        };
        let _ = writeln!(
            out,
            "\n{}: reference {:.5} {unit} ({how})\n",
            quantity.label(),
            reference * scale
        );
        let _ = writeln!(
            out,
            "| series | h (m) | tetra | value ({unit}) | error | wall (s) |\n|---|---:|---:|---:|---:|---:|"
        );
        for (label, pts) in series(points, quantity) {
            for p in &pts {
                let _ = writeln!(
                    out,
                    "| {label} | {:.4} | {} | {:.4} | {:+.3} % | {:.2} |",
                    p.h_m,
                    p.tetra,
                    p.value * scale,
                    100.0 * (p.value - reference) / reference,
                    p.wall_s
                );
            }
            if let Some(order) = convergence_order(&pts, reference) {
                let _ = writeln!(out, "| {label}: observed order | | | | {order:.2} | |");
            }
        }
    }
    out
}

/// Draws the 2 × 2 chart (error vs wall time, error vs h; deflection and frequency) to
/// `PREFIX.svg` and `PREFIX.png`.
pub fn draw(points: &[RunPoint], prefix: &Path) -> Result<Vec<PathBuf>> {
    write_svg_png(&SpeedAccuracyChart(points), prefix, (1200, 900))
}

struct SpeedAccuracyChart<'a>(&'a [RunPoint]);

impl Figure for SpeedAccuracyChart<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, plotters::coord::Shift>,
    ) -> std::result::Result<(), String> {
        draw_on(root, self.0)
    }
}

fn draw_on<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    points: &[RunPoint],
) -> std::result::Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let panels = root.split_evenly((2, 2));
    let palette = &PALETTE[..5];
    for (row, quantity) in [Quantity::Deflection, Quantity::Frequency]
        .into_iter()
        .enumerate()
    {
        let Some((reference, _)) = reference(points, quantity) else {
            continue;
        };
        let groups = series(points, quantity);
        let error = |p: &RunPoint| ((p.value - reference) / reference).abs().max(1e-7);
        for col in 0..2 {
            let area = &panels[2 * row + col];
            let xs: Vec<f64> = groups
                .iter()
                .flat_map(|g| g.1.iter().map(|p| if col == 0 { p.wall_s } else { p.h_m }))
                .collect();
            let ys: Vec<f64> = groups
                .iter()
                .flat_map(|g| g.1.iter().map(|p| error(p)))
                .collect();
            if xs.is_empty() {
                continue;
            }
            let (x0, x1) = bounds(&xs);
            let (y0, y1) = bounds(&ys);
            let title = format!(
                "{} error vs {}",
                quantity.label(),
                if col == 0 { "wall time" } else { "mesh size" }
            );
            let mut chart = ChartBuilder::on(area)
                .caption(title, ("sans-serif", 20))
                .margin(10)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc(if col == 0 { "wall time (s)" } else { "h (m)" })
                .y_desc("relative error")
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .x_labels(6)
                .x_label_formatter(&|v| format!("{v}"))
                .draw()
                .map_err(err)?;
            for (i, (label, pts)) in groups.iter().enumerate() {
                let colour = palette[i % palette.len()];
                let line: Vec<(f64, f64)> = pts
                    .iter()
                    .map(|p| (if col == 0 { p.wall_s } else { p.h_m }, error(p)))
                    .collect();
                chart
                    .draw_series(LineSeries::new(line.clone(), colour.stroke_width(2)))
                    .map_err(err)?
                    .label(label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                    });
                chart
                    .draw_series(
                        line.iter()
                            .map(|&(x, y)| Circle::new((x, y), 4, colour.filled())),
                    )
                    .map_err(err)?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(err)?;
        }
    }
    Ok(())
}

/// Log-axis bounds with a margin of a quarter decade.
fn bounds(values: &[f64]) -> (f64, f64) {
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (lo / 1.8, hi * 1.8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(method: Method, h: f64, value: f64) -> RunPoint {
        RunPoint {
            method,
            quantity: Quantity::Deflection,
            value,
            wall_s: 1.0 / h,
            tetra: 1,
            h_m: h,
            dt_factor: (method == Method::Qdem).then_some(0.8),
            source: PathBuf::new(),
        }
    }

    #[test]
    fn richardson_reference_and_order_two_recovered() {
        // value = 1 − 3 h²: the extrapolation gives 1 and the observed order is 2.
        let f = |h: f64| 1.0 - 3.0 * h * h;
        let points: Vec<RunPoint> = [0.1, 0.05, 0.025]
            .iter()
            .map(|&h| p(Method::Fem, h, f(h)))
            .collect();
        let (r, _) = reference(&points, Quantity::Deflection).unwrap();
        assert!((r - 1.0).abs() < 1e-12, "{r}");
        let refs: Vec<&RunPoint> = points.iter().collect();
        let order = convergence_order(&refs, r).unwrap();
        assert!((order - 2.0).abs() < 1e-9, "{order}");
    }
}
