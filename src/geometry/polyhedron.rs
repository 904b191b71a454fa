//! Mass properties of closed triangle surfaces and convex hulls.
//!
//! Volume, centroid and second moments come from the divergence theorem: the solid is the
//! signed sum of the tetrahedra (origin, a, b, c) over its outward-oriented triangles, so
//! the result is exact for any closed, consistently oriented surface (convex or not).

use crate::{Error, Result};
use nalgebra::{Matrix3, Point3, Vector3};

/// Volume, surface area, centroid and inertia of a homogeneous solid of unit density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    /// Enclosed volume (m³); positive for an outward-oriented surface.
    pub volume: f64,
    /// Surface area (m²).
    pub area: f64,
    /// Centre of mass (m).
    pub centroid: Point3<f64>,
    /// Inertia tensor about the centroid for unit density (m⁵); multiply by ρ for kg·m².
    pub inertia: Matrix3<f64>,
}

/// Mass properties of the solid bounded by `triangles` (0-based indices into `vertices`,
/// outward oriented: counter-clockwise seen from outside).
pub fn mass_properties(vertices: &[Point3<f64>], triangles: &[[u32; 3]]) -> MassProperties {
    // Shift to a point near the solid so that large coordinates do not cancel badly.
    let origin = vertices
        .first()
        .map(|p| p.coords)
        .unwrap_or_else(Vector3::zeros);
    // ∫ x xᵀ dV over the tetrahedron (0, a, b, c) is det · A C Aᵀ with A = [a b c] and
    // C = (1 + δ_ij) / 120 (the canonical tetrahedron's second moments).
    let canonical = Matrix3::new(2.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 2.0) / 120.0;
    let mut volume = 0.0;
    let mut area = 0.0;
    let mut first_moment = Vector3::zeros();
    let mut second_moment = Matrix3::zeros();
    for tri in triangles {
        let a = vertices[tri[0] as usize].coords - origin;
        let b = vertices[tri[1] as usize].coords - origin;
        let c = vertices[tri[2] as usize].coords - origin;
        let det = a.dot(&b.cross(&c));
        volume += det / 6.0;
        area += 0.5 * (b - a).cross(&(c - a)).norm();
        first_moment += det / 24.0 * (a + b + c);
        let edges = Matrix3::from_columns(&[a, b, c]);
        second_moment += det * edges * canonical * edges.transpose();
    }
    let centroid_local = if volume != 0.0 {
        first_moment / volume
    } else {
        Vector3::zeros()
    };
    let central = second_moment - volume * centroid_local * centroid_local.transpose();
    let inertia = Matrix3::identity() * central.trace() - central;
    MassProperties {
        volume,
        area,
        centroid: Point3::from(centroid_local + origin),
        inertia,
    }
}

/// A triangulated surface: vertices and 0-based, outward-oriented triangles.
pub type TriangleSurface = (Vec<Point3<f64>>, Vec<[u32; 3]>);

/// The convex hull of `points`: its vertices and outward-oriented triangles.
///
/// Errors (instead of panicking) on degenerate input such as fewer than four points or
/// coplanar points.
pub fn convex_hull(points: &[Point3<f64>]) -> Result<TriangleSurface> {
    if points.len() < 4 {
        return Err(Error::Message(format!(
            "convex hull of {} points: at least 4 are needed",
            points.len()
        )));
    }
    parry3d_f64::transformation::try_convex_hull(points)
        .map_err(|e| Error::Message(format!("convex hull of {} points: {e}", points.len())))
}

/// The volume of the convex hull of `points`.
pub fn convex_hull_volume(points: &[Point3<f64>]) -> Result<f64> {
    let (vertices, triangles) = convex_hull(points)?;
    Ok(mass_properties(&vertices, &triangles).volume)
}
