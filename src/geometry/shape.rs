//! Shape descriptors of stones: PCA extents, Wadell sphericity, sieve size, summaries.
//!
//! Definitions follow the grain library's README (`/work/shared/grains/README.md`):
//! L ≥ I ≥ S are the extents (max − min) of the vertices along the principal axes of the
//! vertex cloud's covariance; the sphericity is π d_eq² / area with d_eq the diameter of
//! the sphere of equal volume.

use super::polyhedron::mass_properties;
use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};

/// Extents `[L, I, S]` (L ≥ I ≥ S) of `points` along the principal axes of their covariance.
/// Fewer than two points give zeros.
pub fn pca_extents(points: &[Point3<f64>]) -> [f64; 3] {
    if points.len() < 2 {
        return [0.0; 3];
    }
    let mean = points.iter().map(|p| p.coords).sum::<Vector3<f64>>() / points.len() as f64;
    let covariance = points
        .iter()
        .map(|p| {
            let d = p.coords - mean;
            d * d.transpose()
        })
        .sum::<Matrix3<f64>>()
        / points.len() as f64;
    let axes = SymmetricEigen::new(covariance).eigenvectors;
    let mut extents = [0.0; 3];
    for (k, extent) in extents.iter_mut().enumerate() {
        let axis = axes.column(k);
        let (lo, hi) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            let t = (p.coords - mean).dot(&axis);
            (lo.min(t), hi.max(t))
        });
        *extent = hi - lo;
    }
    extents.sort_by(|a, b| b.total_cmp(a));
    extents
}

/// Indices of the corners of a polyhedral surface: the vertices whose incident triangles
/// span three independent normal directions. Mesh nodes inside a flat face (one normal)
/// or along a straight edge (two normals) are left out, so a meshed polyhedron gives the
/// same vertex set as its CAD definition.
pub fn corner_vertices(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut normal_moments = vec![Matrix3::<f64>::zeros(); vertices.len()];
    for tri in triangles {
        let [a, b, c] = tri.map(|i| vertices[i as usize]);
        let normal = (b - a).cross(&(c - a));
        let norm = normal.norm();
        if norm == 0.0 {
            continue;
        }
        let n = normal / norm;
        for &i in tri {
            normal_moments[i as usize] += n * n.transpose();
        }
    }
    normal_moments
        .iter()
        .enumerate()
        .filter(|(_, m)| {
            let eigen = m.symmetric_eigenvalues();
            let largest = eigen.max();
            // Planar CAD faces are flat to round-off; true corners of cut stones have
            // faces at least a few degrees apart (eigenvalue ≳ 1e-3).
            largest > 0.0 && eigen.min() > 1e-6 * largest
        })
        .map(|(i, _)| i as u32)
        .collect()
}

/// Wadell sphericity π d_eq² / area of a solid of `volume` and surface `area`.
pub fn wadell_sphericity(volume: f64, area: f64) -> f64 {
    std::f64::consts::PI * equivalent_diameter(volume).powi(2) / area
}

/// Diameter of the sphere of the same volume.
pub fn equivalent_diameter(volume: f64) -> f64 {
    (6.0 * volume / std::f64::consts::PI).cbrt()
}

/// The square-mesh sieve size of a stone of intermediate and short extents `i`, `s`:
/// the smallest square aperture an elliptical I × S cross-section passes through, its
/// width at 45°, √((I² + S²)/2). (A rectangular cross-section would need I; crushed
/// stones have bevelled corners, between the two.) See `docs/stones.md`.
pub fn sieve_size(i: f64, s: f64) -> f64 {
    (0.5 * (i * i + s * s)).sqrt()
}

/// Shape measures of one stone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeMeasures {
    /// PCA extents L ≥ I ≥ S (m).
    pub extents: [f64; 3],
    /// Volume (m³).
    pub volume: f64,
    /// Surface area (m²).
    pub area: f64,
    /// Equivalent-sphere diameter (m).
    pub d_eq: f64,
    /// Wadell sphericity.
    pub sphericity: f64,
}

impl ShapeMeasures {
    /// Measures of the polyhedron of `triangles` (outward oriented), with its PCA extents
    /// taken over `pca_points` (its corners).
    pub fn of_polyhedron(
        vertices: &[Point3<f64>],
        triangles: &[[u32; 3]],
        pca_points: &[Point3<f64>],
    ) -> Self {
        let mass = mass_properties(vertices, triangles);
        ShapeMeasures {
            extents: pca_extents(pca_points),
            volume: mass.volume,
            area: mass.area,
            d_eq: equivalent_diameter(mass.volume),
            sphericity: wadell_sphericity(mass.volume, mass.area),
        }
    }

    /// Elongation I/L.
    pub fn elongation(&self) -> f64 {
        self.extents[1] / self.extents[0]
    }

    /// Flatness S/I.
    pub fn flatness(&self) -> f64 {
        self.extents[2] / self.extents[1]
    }

    /// Sieve size √((I² + S²)/2) (m), see [`sieve_size`].
    pub fn sieve_size(&self) -> f64 {
        sieve_size(self.extents[1], self.extents[2])
    }
}

/// Mean, standard deviation and percentiles of a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Number of values.
    pub count: usize,
    /// Arithmetic mean.
    pub mean: f64,
    /// Standard deviation (population, divisor n).
    pub sd: f64,
    /// Smallest value.
    pub min: f64,
    /// 5th percentile (linear interpolation between order statistics).
    pub p5: f64,
    /// Median.
    pub p50: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Largest value.
    pub max: f64,
}

impl Summary {
    /// The summary of `values`; `None` when empty or when a value is not finite.
    pub fn of(values: &[f64]) -> Option<Self> {
        if values.is_empty() || values.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let n = sorted.len() as f64;
        let mean = sorted.iter().sum::<f64>() / n;
        let variance = sorted.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        let percentile = |q: f64| {
            let rank = q * (sorted.len() - 1) as f64;
            let lo = rank.floor() as usize;
            let hi = rank.ceil() as usize;
            sorted[lo] + (sorted[hi] - sorted[lo]) * (rank - lo as f64)
        };
        Some(Summary {
            count: sorted.len(),
            mean,
            sd: variance.sqrt(),
            min: sorted[0],
            p5: percentile(0.05),
            p50: percentile(0.5),
            p95: percentile(0.95),
            max: sorted[sorted.len() - 1],
        })
    }
}
