//! Statistics of a generated stone family (`meshes/stones/stone_NNN.msh`) beside the real
//! grain library's, and its grading against EN 13450 (railway ballast 31.5/50 mm).
//!
//! This is what `ballast-post stones DIR [--library FILE]` prints; see `docs/stones.md`.

use super::grain_library::read_grain_library;
use super::polyhedron::convex_hull_volume;
use super::shape::{corner_vertices, ShapeMeasures, Summary};
use crate::mesh::{read_msh, TetMesh};
use crate::{Error, Result};
use nalgebra::Point3;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A grading band: sieve size (mm) and percent passing by mass (low, high).
pub type GradingBand = [(f64, f64, f64); 5];

/// EN 13450 railway ballast 31.5/50 mm, grading categories A, B and C: percent passing by
/// mass at the 22.4, 31.5, 40, 50 and 63 mm square-mesh sieves (EN 13450:2002 Table 2,
/// kept in EN 13450:2013 Table 1). The family is built on the middle of category A.
pub const EN13450_31_5_50: [(&str, GradingBand); 3] = [
    (
        "A",
        [
            (22.4, 0.0, 3.0),
            (31.5, 1.0, 25.0),
            (40.0, 30.0, 65.0),
            (50.0, 70.0, 99.0),
            (63.0, 100.0, 100.0),
        ],
    ),
    (
        "B",
        [
            (22.4, 0.0, 3.0),
            (31.5, 1.0, 25.0),
            (40.0, 30.0, 70.0),
            (50.0, 70.0, 99.0),
            (63.0, 100.0, 100.0),
        ],
    ),
    (
        "C",
        [
            (22.4, 0.0, 3.0),
            (31.5, 1.0, 25.0),
            (40.0, 25.0, 75.0),
            (50.0, 65.0, 99.0),
            (63.0, 100.0, 100.0),
        ],
    ),
];

/// Measures of one meshed stone.
#[derive(Debug, Clone, PartialEq)]
pub struct StoneMeasures {
    /// The mesh file.
    pub source: PathBuf,
    /// Shape of the stone's boundary polyhedron (PCA extents over its corners).
    pub shape: ShapeMeasures,
    /// Number of tetrahedra.
    pub tets: usize,
    /// Sum of the tetrahedra's volumes (m³).
    pub mesh_volume: f64,
    /// Convex hull volume of the nodes / mesh volume: 1 for a convex stone.
    pub hull_ratio: f64,
    /// Worst tetra quality, normalised radius ratio `3 r_in / r_circ` (1 = regular).
    pub min_quality: f64,
    /// Mean tetra quality (same measure).
    pub mean_quality: f64,
    /// Smallest tetra altitude / the stone's equivalent diameter d_eq: the explicit
    /// stable time step of a deformable stone scales with it.
    pub min_altitude_ratio: f64,
}

/// Measures a stone mesh: shape from its boundary triangles, convexity from the hull of
/// its nodes. Errors when the mesh has no tetrahedra or no boundary.
pub fn measure_stone_mesh(mesh: &TetMesh) -> Result<StoneMeasures> {
    if mesh.tets.is_empty() || mesh.boundary.is_empty() {
        return Err(Error::invalid(
            &mesh.source,
            "a stone mesh needs tetrahedra and a boundary",
        ));
    }
    let mesh_volume: f64 = mesh
        .tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|i| mesh.nodes[i as usize]);
            (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
        })
        .sum();
    let corners: Vec<Point3<f64>> = corner_vertices(&mesh.nodes, &mesh.boundary)
        .into_iter()
        .map(|i| mesh.nodes[i as usize])
        .collect();
    let shape = ShapeMeasures::of_polyhedron(&mesh.nodes, &mesh.boundary, &corners);
    let hull_volume =
        convex_hull_volume(&mesh.nodes).map_err(|e| Error::invalid(&mesh.source, e.to_string()))?;
    let quality = mesh.quality();
    Ok(StoneMeasures {
        source: mesh.source.clone(),
        shape,
        tets: mesh.tets.len(),
        mesh_volume,
        hull_ratio: hull_volume / mesh_volume,
        min_quality: quality.min_quality,
        mean_quality: quality.mean_quality,
        min_altitude_ratio: quality.min_altitude_m / shape.d_eq,
    })
}

/// Reads and measures every `*.msh` file of `dir`, in file-name order.
pub fn measure_stone_dir(dir: &Path) -> Result<Vec<StoneMeasures>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut paths = Vec::new();
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.extension().is_some_and(|ext| ext == "msh") {
            paths.push(path);
        }
    }
    paths.sort();
    if paths.is_empty() {
        return Err(Error::Message(format!(
            "{}: no .msh stones (build them with `make stones`)",
            dir.display()
        )));
    }
    paths
        .iter()
        .map(|path| measure_stone_mesh(&read_msh(path)?))
        .collect()
}

/// Shape measures of every grain of a grain library file.
pub fn library_shapes(path: &Path) -> Result<Vec<ShapeMeasures>> {
    Ok(read_grain_library(path)?
        .iter()
        .map(|grain| grain.shape())
        .collect())
}

/// Percent of the total volume (mass) of `shapes` whose sieve size is at most `sieve_m`.
pub fn percent_passing(shapes: &[ShapeMeasures], sieve_m: f64) -> f64 {
    let total: f64 = shapes.iter().map(|s| s.volume).sum();
    let passing: f64 = shapes
        .iter()
        .filter(|s| s.sieve_size() <= sieve_m)
        .map(|s| s.volume)
        .sum();
    // `+ 0.0` turns the empty sum (-0.0) into 0.
    100.0 * passing / total + 0.0
}

/// The family-vs-library table printed by `ballast-post stones DIR [--library FILE]`:
/// shape statistics side by side (mean, sd, p5, p50, p95), mesh checks of the family,
/// and the grading (percent passing by mass) against the EN 13450 31.5/50 bands.
pub fn stone_family_report(stone_dir: &Path, library: Option<&Path>) -> Result<String> {
    let stones = measure_stone_dir(stone_dir)?;
    let family: Vec<ShapeMeasures> = stones.iter().map(|s| s.shape).collect();
    let library_shapes = library.map(library_shapes).transpose()?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "stone family: {} ({} stones)",
        stone_dir.display(),
        stones.len()
    );
    if let (Some(path), Some(shapes)) = (library, &library_shapes) {
        let _ = writeln!(
            out,
            "library:      {} ({} grains)",
            path.display(),
            shapes.len()
        );
    }
    let _ = writeln!(out);
    let header = "          mean       sd       p5      p50      p95";
    let _ = write!(out, "{:<22}|{header}", "quantity (family)");
    if library_shapes.is_some() {
        let _ = write!(out, " |{header}");
    }
    let _ = writeln!(out);

    type Quantity = (&'static str, fn(&ShapeMeasures) -> f64);
    let quantities: [Quantity; 9] = [
        ("d_eq (mm)", |s| s.d_eq * 1e3),
        ("L (mm)", |s| s.extents[0] * 1e3),
        ("I (mm)", |s| s.extents[1] * 1e3),
        ("S (mm)", |s| s.extents[2] * 1e3),
        ("elongation I/L", |s| s.elongation()),
        ("flatness S/I", |s| s.flatness()),
        ("Wadell sphericity", |s| s.sphericity),
        ("volume (cm3)", |s| s.volume * 1e6),
        ("sieve size (mm)", |s| s.sieve_size() * 1e3),
    ];
    for (name, value) in quantities {
        let _ = write!(out, "{name:<22}|");
        write_summary(&mut out, &family.iter().map(value).collect::<Vec<_>>());
        if let Some(shapes) = &library_shapes {
            let _ = write!(out, " |");
            write_summary(&mut out, &shapes.iter().map(value).collect::<Vec<_>>());
        }
        let _ = writeln!(out);
    }
    let _ = write!(out, "{:<22}|", "tetra per stone");
    write_summary(
        &mut out,
        &stones.iter().map(|s| s.tets as f64).collect::<Vec<_>>(),
    );
    let _ = writeln!(out);
    let tets_min = stones.iter().map(|s| s.tets).min().unwrap_or(0);
    let tets_max = stones.iter().map(|s| s.tets).max().unwrap_or(0);
    let hull_min = stones
        .iter()
        .map(|s| s.hull_ratio)
        .fold(f64::INFINITY, f64::min);
    let _ = writeln!(
        out,
        "tetra per stone min..max: {tets_min}..{tets_max}; hull/mesh volume min: {hull_min:.5}"
    );
    let fold_min =
        |f: fn(&StoneMeasures) -> f64| stones.iter().map(f).fold(f64::INFINITY, f64::min);
    let quality_min = fold_min(|s| s.min_quality);
    let altitude_min = fold_min(|s| s.min_altitude_ratio);
    let quality_mean = stones
        .iter()
        .map(|s| s.mean_quality * s.tets as f64)
        .sum::<f64>()
        / stones.iter().map(|s| s.tets as f64).sum::<f64>();
    let _ = writeln!(
        out,
        "tetra quality (3 r_in / r_circ) min: {quality_min:.3}, mean: {quality_mean:.3}; \
         min altitude / d_eq: {:.2} %",
        100.0 * altitude_min
    );
    if let Some(shapes) = &library_shapes {
        let fraction = |set: &[ShapeMeasures]| {
            set.iter()
                .filter(|s| s.extents[0] > 3.0 * s.extents[2])
                .count() as f64
                / set.len() as f64
        };
        let _ = writeln!(
            out,
            "fraction with L/S > 3: family {:.3}, library {:.3}",
            fraction(&family),
            fraction(shapes)
        );
    }

    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "grading: percent passing by mass (volume), sieve size = sqrt((I^2 + S^2)/2)"
    );
    let _ = write!(out, "{:>10} {:>8}", "sieve mm", "family");
    if library_shapes.is_some() {
        let _ = write!(out, " {:>8}", "library");
    }
    for (category, _) in EN13450_31_5_50 {
        let _ = write!(out, " {:>13}", format!("EN 13450 {category}"));
    }
    let _ = writeln!(out);
    for (k, &(sieve_mm, _, _)) in EN13450_31_5_50[0].1.iter().enumerate() {
        let passing = percent_passing(&family, sieve_mm * 1e-3);
        let _ = write!(out, "{sieve_mm:>10.1} {passing:>8.1}");
        if let Some(shapes) = &library_shapes {
            let _ = write!(out, " {:>8.1}", percent_passing(shapes, sieve_mm * 1e-3));
        }
        for (_, band) in EN13450_31_5_50 {
            let (_, lo, hi) = band[k];
            let _ = write!(out, " {:>13}", format!("{lo:.0}-{hi:.0}"));
        }
        let _ = writeln!(out);
    }
    Ok(out)
}

fn write_summary(out: &mut String, values: &[f64]) {
    match Summary::of(values) {
        Some(s) => {
            let _ = write!(
                out,
                " {:>9.3} {:>8.3} {:>8.3} {:>8.3} {:>8.3}",
                s.mean, s.sd, s.p5, s.p50, s.p95
            );
        }
        None => {
            let _ = write!(out, " {:>45}", "-");
        }
    }
}
