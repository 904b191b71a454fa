//! Geometry of single linear tetrahedra (volume, altitude, shape quality) and the
//! whole-mesh quality report used to choose the stable explicit time step.

use super::TetMesh;
use nalgebra::Point3;
use std::fmt;

/// Signed volume of the tetrahedron `(a, b, c, d)`: positive when `d` lies on the side
/// of triangle `(a, b, c)` that its right-hand normal points to (gmsh's orientation).
pub fn tet_signed_volume(corners: [Point3<f64>; 4]) -> f64 {
    let [a, b, c, d] = corners;
    (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
}

/// Areas of the four faces, in the order of the faces opposite corners 0, 1, 2, 3.
pub fn tet_face_areas(corners: [Point3<f64>; 4]) -> [f64; 4] {
    let [a, b, c, d] = corners;
    let area =
        |p: Point3<f64>, q: Point3<f64>, r: Point3<f64>| 0.5 * (q - p).cross(&(r - p)).norm();
    [area(b, c, d), area(a, c, d), area(a, b, d), area(a, b, c)]
}

/// The smallest altitude (distance from a corner to the plane of its opposite face):
/// the length that bounds the stable explicit time step of a lumped-mass tetra.
pub fn tet_min_altitude(corners: [Point3<f64>; 4]) -> f64 {
    let volume = tet_signed_volume(corners).abs();
    let largest_face = tet_face_areas(corners).into_iter().fold(0.0, f64::max);
    if largest_face > 0.0 {
        3.0 * volume / largest_face
    } else {
        0.0
    }
}

/// Normalised radius ratio `3 · r_in / r_circ` in `[0, 1]`: 1 for the regular tetra,
/// 0 for a flat one. Orientation is ignored (the absolute volume is used).
pub fn tet_quality(corners: [Point3<f64>; 4]) -> f64 {
    let [a, b, c, d] = corners;
    let (u, v, w) = (b - a, c - a, d - a);
    let six_volume = u.dot(&v.cross(&w));
    let face_area_sum: f64 = tet_face_areas(corners).iter().sum();
    if six_volume == 0.0 || face_area_sum == 0.0 {
        return 0.0;
    }
    // Circumcentre relative to `a` (closed form of the 3×3 linear system).
    let centre = (v.cross(&w) * u.norm_squared()
        + w.cross(&u) * v.norm_squared()
        + u.cross(&v) * w.norm_squared())
        / (2.0 * six_volume);
    let circumradius = centre.norm();
    let inradius = 0.5 * six_volume.abs() / face_area_sum; // 3V / ΣA
    (3.0 * inradius / circumradius).min(1.0)
}

/// Size and shape summary of a [`TetMesh`] (see [`TetMesh::quality`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshQuality {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of tetrahedra.
    pub tets: usize,
    /// Total volume in m³.
    pub volume_m3: f64,
    /// Smallest tetra altitude in metres (sets the stable explicit time step).
    pub min_altitude_m: f64,
    /// Worst normalised radius ratio `3 · r_in / r_circ` (1 = regular tetra).
    pub min_quality: f64,
    /// Mean normalised radius ratio over all tetrahedra.
    pub mean_quality: f64,
}

impl fmt::Display for MeshQuality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} nodes, {} tetrahedra, volume {:.6e} m³, min altitude {:.4e} m, quality min {:.3} mean {:.3}",
            self.nodes,
            self.tets,
            self.volume_m3,
            self.min_altitude_m,
            self.min_quality,
            self.mean_quality
        )
    }
}

impl TetMesh {
    /// The four corner coordinates of tetrahedron `tet`.
    ///
    /// # Panics
    /// If `tet` is out of range (an index, not user input).
    pub fn tet_corners(&self, tet: usize) -> [Point3<f64>; 4] {
        self.tets[tet].map(|n| self.nodes[n as usize])
    }

    /// Signed volume of tetrahedron `tet` in m³ (positive for a mesh from [`super::read_msh`]).
    ///
    /// # Panics
    /// If `tet` is out of range (an index, not user input).
    pub fn tet_volume(&self, tet: usize) -> f64 {
        tet_signed_volume(self.tet_corners(tet))
    }

    /// Total volume of the mesh in m³ (sum of the signed tetra volumes).
    pub fn total_volume(&self) -> f64 {
        (0..self.tets.len()).map(|t| self.tet_volume(t)).sum()
    }

    /// Size and shape summary: counts, volume, smallest altitude, radius-ratio quality.
    pub fn quality(&self) -> MeshQuality {
        let mut min_altitude_m = f64::INFINITY;
        let mut min_quality = f64::INFINITY;
        let mut quality_sum = 0.0;
        for tet in 0..self.tets.len() {
            let corners = self.tet_corners(tet);
            min_altitude_m = min_altitude_m.min(tet_min_altitude(corners));
            let quality = tet_quality(corners);
            min_quality = min_quality.min(quality);
            quality_sum += quality;
        }
        let tets = self.tets.len();
        MeshQuality {
            nodes: self.nodes.len(),
            tets,
            volume_m3: self.total_volume(),
            min_altitude_m: if tets == 0 { 0.0 } else { min_altitude_m },
            min_quality: if tets == 0 { 0.0 } else { min_quality },
            mean_quality: if tets == 0 {
                0.0
            } else {
                quality_sum / tets as f64
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corner_tet(scale: f64) -> [Point3<f64>; 4] {
        [
            Point3::origin(),
            Point3::new(scale, 0.0, 0.0),
            Point3::new(0.0, scale, 0.0),
            Point3::new(0.0, 0.0, scale),
        ]
    }

    fn regular_tet() -> [Point3<f64>; 4] {
        [
            Point3::new(1.0, 1.0, 1.0),
            Point3::new(1.0, -1.0, -1.0),
            Point3::new(-1.0, 1.0, -1.0),
            Point3::new(-1.0, -1.0, 1.0),
        ]
    }

    #[test]
    fn corner_tet_volume_and_orientation() {
        let [a, b, c, d] = corner_tet(2.0);
        assert!((tet_signed_volume([a, b, c, d]) - 8.0 / 6.0).abs() < 1e-15);
        assert!((tet_signed_volume([a, c, b, d]) + 8.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn regular_tet_has_quality_one() {
        assert!((tet_quality(regular_tet()) - 1.0).abs() < 1e-12);
        // Edge 2√2: altitude = edge · √(2/3).
        let altitude = 2.0 * 2f64.sqrt() * (2.0f64 / 3.0).sqrt();
        assert!((tet_min_altitude(regular_tet()) - altitude).abs() < 1e-12);
    }

    #[test]
    fn corner_tet_quality_and_altitude() {
        // r_in = 1/(3+√3), R = √3/2 for the unit corner tetra.
        let expected = 3.0 / (3.0 + 3f64.sqrt()) / (3f64.sqrt() / 2.0);
        assert!((tet_quality(corner_tet(1.0)) - expected).abs() < 1e-12);
        // Smallest altitude: from the origin to the slanted face x + y + z = 1.
        assert!((tet_min_altitude(corner_tet(1.0)) - 1.0 / 3f64.sqrt()).abs() < 1e-12);
        // Quality is scale-invariant and orientation-blind.
        let [a, b, c, d] = corner_tet(1e-3);
        assert!((tet_quality([a, c, b, d]) - expected).abs() < 1e-9);
    }

    #[test]
    fn flat_tet_has_quality_zero() {
        let flat = [
            Point3::origin(),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        assert_eq!(tet_quality(flat), 0.0);
        assert_eq!(tet_min_altitude(flat), 0.0);
    }
}
