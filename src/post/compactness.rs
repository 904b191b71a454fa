//! `ballast-post compactness`: the solid fraction of a `ballast-pack` bed, measured
//! again from its packing file in the control boxes its summary names, and by depth
//! in each box ([`depth_profile`]).
//!
//! Why: a box under a sleeper a few stones high holds the loose band that any flat face
//! leaves in a granular bed (about half a grain deep), so its compactness sits below
//! the bulk figures published for ballast in track, which are measured away from faces.
//! The profile shows the band and the bulk apart. The recomputed values equal the
//! summary's (the packing read back gives the same bodies to round-off), which the
//! tests check.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde_json::{json, Value};

use super::chart::{write_svg_png, LinePanel, Stacked};
use super::track_spectra::with_suffix;
use crate::geometry::ControlBox;
use crate::nscd::body::Body;
use crate::nscd::packed::{packed_bodies, PackedMaterials, Stuff};
use crate::pack::report::{solid_fraction, BoxProfile, PROFILE_SLICE_OVER_D50};
use crate::pack::Packing;
use crate::{Error, Result};

/// The published band of solid fraction for ballast in track (porosity 0.35–0.45;
/// Selig & Waters 1994, Indraratna et al. 2011): drawn on the chart.
pub const PUBLISHED_BAND: (f64, f64) = (0.55, 0.65);

/// One control box of a bed, measured again.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxFigure {
    /// Its name in `summary.json` (`under_sleeper_1` …).
    pub name: String,
    /// The box.
    pub bx: ControlBox,
    /// The compactness `ballast-pack` wrote.
    pub summary_value: f64,
    /// The compactness of the packing file's stones in it.
    pub value: f64,
}

/// What `ballast-post compactness` finds in a bed directory.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The bed directory (packing.toml, summary.json).
    pub dir: PathBuf,
    /// Stones in the packing.
    pub stones: usize,
    /// The summary's d50 (m).
    pub d50_m: f64,
    /// Every control box of the summary, in its order.
    pub boxes: Vec<BoxFigure>,
    /// Each box's profile by depth below its top.
    pub profiles: Vec<BoxProfile>,
}

/// Reads `dir/packing.toml` and `dir/summary.json` and measures every control box of the
/// summary and its profile in slices near `slice_m` high (default a quarter of d50).
pub fn analyse(dir: &Path, slice_m: Option<f64>) -> Result<Report> {
    let summary_path = dir.join("summary.json");
    let summary = super::read_json(&summary_path)?;
    let figures = &summary["figures"];
    let d50_m = figures["d50_m"]
        .as_f64()
        .filter(|d| *d > 0.0)
        .ok_or_else(|| {
            Error::invalid(
                &summary_path,
                "figures.d50_m: missing or not a positive number (not a ballast-pack summary?)",
            )
        })?;
    let listed = figures["compactness"].as_array().ok_or_else(|| {
        Error::invalid(
            &summary_path,
            "figures.compactness: missing or not a list (not a ballast-pack summary?)",
        )
    })?;
    let slice = match slice_m {
        Some(s) if !(s.is_finite() && s > 0.0) => {
            return Err(Error::Message(format!(
                "--slice {s}: the slice height must be a positive length in metres"
            )))
        }
        Some(s) => s,
        None => PROFILE_SLICE_OVER_D50 * d50_m,
    };

    let packing_path = dir.join("packing.toml");
    let packing = Packing::read(&packing_path)?;
    let materials = PackedMaterials {
        stones: Stuff {
            material: 0,
            density: 1.0,
        },
        sleepers: None,
        walls: None,
    };
    let bodies = packed_bodies(&packing_path, &packing, &materials)?.bodies;
    let stones: Vec<&Body> = bodies.iter().collect();
    let period = packing.period();

    let mut boxes = Vec::with_capacity(listed.len());
    let mut profiles = Vec::with_capacity(listed.len());
    for (k, entry) in listed.iter().enumerate() {
        let key = |what: &str| format!("figures.compactness[{k}].{what}");
        let name = entry["box"]
            .as_str()
            .ok_or_else(|| Error::invalid(&summary_path, format!("{}: missing", key("box"))))?;
        let corner = |what: &str| -> Result<Point3<f64>> {
            let v: Vec<f64> = entry[what]
                .as_array()
                .map(|a| a.iter().filter_map(Value::as_f64).collect())
                .unwrap_or_default();
            match v[..] {
                [x, y, z] => Ok(Point3::new(x, y, z)),
                _ => Err(Error::invalid(
                    &summary_path,
                    format!("{}: not three numbers", key(what)),
                )),
            }
        };
        let bx = ControlBox {
            min: corner("min_m")?,
            max: corner("max_m")?,
        };
        boxes.push(BoxFigure {
            name: name.to_string(),
            bx,
            summary_value: entry["value"].as_f64().unwrap_or(f64::NAN),
            value: solid_fraction(&stones, &bx, period.as_ref()),
        });
        profiles.push(BoxProfile::measure(
            &stones,
            name,
            &bx,
            slice,
            d50_m,
            period.as_ref(),
        ));
    }
    Ok(Report {
        dir: dir.to_path_buf(),
        stones: packing.stones.len(),
        d50_m,
        boxes,
        profiles,
    })
}

impl Report {
    /// The report as markdown: a table of the boxes, then each box's profile.
    pub fn table(&self) -> String {
        let mut s = format!(
            "Bed {}: {} stones, d50 {:.1} mm; published for ballast in track: {}–{}\n\n",
            self.dir.display(),
            self.stones,
            1e3 * self.d50_m,
            PUBLISHED_BAND.0,
            PUBLISHED_BAND.1
        );
        s.push_str(
            "| box | height mm | compactness | in summary.json | top slice | below its top d50 |\n\
             |---|---:|---:|---:|---:|---:|\n",
        );
        for (b, p) in self.boxes.iter().zip(&self.profiles) {
            let top = p.slices.first().map_or(f64::NAN, |s| s.value);
            let _ = writeln!(
                s,
                "| {} | {:.1} | {:.4} | {:.4} | {:.3} | {} |",
                b.name,
                1e3 * (b.bx.max.z - b.bx.min.z),
                b.value,
                b.summary_value,
                top,
                p.below_one_d50
                    .map_or("—".to_string(), |v| format!("{v:.4}"))
            );
        }
        s.push_str(
            "\nBy depth below each box's top (the sleeper's underside for `under_sleeper_*`):\n\n",
        );
        for p in &self.profiles {
            let _ = writeln!(s, "- {}", p.line());
        }
        s
    }
}

/// Writes `PREFIX.md`, `PREFIX.json` and the profiles' chart `PREFIX.svg/.png`; returns
/// the paths.
pub fn write_report(report: &Report, prefix: &Path) -> Result<Vec<PathBuf>> {
    let md = with_suffix(prefix, ".md");
    crate::output::write_atomic(&md, report.table().as_bytes())?;
    let js = with_suffix(prefix, ".json");
    let value = json!({
        "dir": report.dir.display().to_string(),
        "stones": report.stones,
        "d50_m": report.d50_m,
        "boxes": report.boxes.iter().map(|b| json!({
            "box": b.name,
            "min_m": [b.bx.min.x, b.bx.min.y, b.bx.min.z],
            "max_m": [b.bx.max.x, b.bx.max.y, b.bx.max.z],
            "value": b.value,
            "summary_value": b.summary_value,
        })).collect::<Vec<_>>(),
        "profiles": report.profiles,
    });
    crate::output::write_json(&js, &value)?;
    let mut paths = vec![md, js];
    paths.extend(write_svg_png(
        &Stacked(vec![profile_panel(report)]),
        &with_suffix(prefix, ".svg"),
        (900, 600),
    )?);
    Ok(paths)
}

/// Solid fraction against depth below each box's top (mm), one line per box, with the
/// published band's edges.
fn profile_panel(report: &Report) -> LinePanel<'static> {
    let deepest = report
        .profiles
        .iter()
        .filter_map(|p| p.slices.last())
        .map(|s| 1e3 * s.to_m)
        .fold(0.0, f64::max);
    let mut series: Vec<(String, Vec<(f64, f64)>)> = report
        .profiles
        .iter()
        .map(|p| {
            let points = p
                .slices
                .iter()
                .map(|s| (500.0 * (s.from_m + s.to_m), s.value))
                .collect();
            (p.name.clone(), points)
        })
        .collect();
    for edge in [PUBLISHED_BAND.0, PUBLISHED_BAND.1] {
        series.push((
            format!("published {edge}"),
            vec![(0.0, edge), (deepest, edge)],
        ));
    }
    LinePanel {
        title: format!(
            "Solid fraction by depth below each box's top — {}",
            report.dir.display()
        ),
        x_desc: "depth below the box's top (mm; under a sleeper: its underside)",
        y_desc: "solid fraction",
        log10_y: false,
        series,
        shade_x: Some((0.0, 500.0 * report.d50_m)),
    }
}
