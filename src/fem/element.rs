//! The linear 4-node tetrahedron: shape-function gradients, stiffness blocks, consistent
//! and lumped mass, and the (constant) strain and stress of an element.

use nalgebra::{Matrix3, Point3, SMatrix, Vector3};

/// Isotropic linear elastic material: Young's modulus (Pa), Poisson's ratio, density (kg/m³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearElastic {
    /// Young's modulus E in Pa.
    pub young_modulus: f64,
    /// Poisson's ratio ν, in (−1, 0.5).
    pub poisson: f64,
    /// Mass density ρ in kg/m³.
    pub density: f64,
}

impl LinearElastic {
    /// Lamé's first parameter λ = Eν / ((1+ν)(1−2ν)).
    pub fn lame_lambda(&self) -> f64 {
        let (e, nu) = (self.young_modulus, self.poisson);
        e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// The shear modulus µ = E / (2(1+ν)).
    pub fn shear_modulus(&self) -> f64 {
        self.young_modulus / (2.0 * (1.0 + self.poisson))
    }

    /// Checks the ranges; the message names the parameter and the reason.
    pub fn check(&self) -> Result<(), String> {
        if !(self.young_modulus.is_finite() && self.young_modulus > 0.0) {
            return Err(format!(
                "young_modulus must be positive and finite, got {}",
                self.young_modulus
            ));
        }
        if !(self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(format!(
                "poisson must lie in (-1, 0.5), got {}",
                self.poisson
            ));
        }
        if !(self.density.is_finite() && self.density > 0.0) {
            return Err(format!(
                "density must be positive and finite, got {}",
                self.density
            ));
        }
        Ok(())
    }

    /// Cauchy stress of a small strain: σ = λ tr(ε) I + 2µ ε.
    pub fn stress(&self, strain: &Matrix3<f64>) -> Matrix3<f64> {
        Matrix3::identity() * (self.lame_lambda() * strain.trace())
            + strain * (2.0 * self.shear_modulus())
    }
}

/// The geometry a linear tetrahedron needs: the gradients of its four shape functions
/// (constant over the element) and its volume.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetGeometry {
    /// ∇N_a for the four vertices, in 1/m.
    pub gradients: [Vector3<f64>; 4],
    /// Volume in m³ (positive whatever the vertex order).
    pub volume: f64,
}

impl TetGeometry {
    /// The gradients and volume of the tetrahedron `x`, or `None` when it is degenerate
    /// (volume below 1e-12 of the cube of its longest edge).
    pub fn new(x: [Point3<f64>; 4]) -> Option<Self> {
        let e1 = x[1] - x[0];
        let e2 = x[2] - x[0];
        let e3 = x[3] - x[0];
        let edge_matrix = Matrix3::from_columns(&[e1, e2, e3]);
        let det = edge_matrix.determinant();
        let longest = [e1, e2, e3, x[2] - x[1], x[3] - x[1], x[3] - x[2]]
            .iter()
            .map(|e| e.norm())
            .fold(0.0, f64::max);
        if !det.is_finite() || det.abs() <= 1e-12 * longest.powi(3) {
            return None;
        }
        // Rows of the inverse edge matrix are the gradients of N1, N2, N3.
        let inverse = edge_matrix.try_inverse()?;
        let g1 = inverse.row(0).transpose();
        let g2 = inverse.row(1).transpose();
        let g3 = inverse.row(2).transpose();
        Some(TetGeometry {
            gradients: [-(g1 + g2 + g3), g1, g2, g3],
            volume: det.abs() / 6.0,
        })
    }

    /// The 3×3 stiffness block coupling the displacement of vertex `b` (columns) to the
    /// force at vertex `a` (rows): V (λ g_a g_bᵀ + µ g_b g_aᵀ + µ (g_a·g_b) I).
    pub fn stiffness_block(&self, a: usize, b: usize, lambda: f64, mu: f64) -> Matrix3<f64> {
        let ga = self.gradients[a];
        let gb = self.gradients[b];
        let v = self.volume;
        (ga * gb.transpose() * lambda + gb * ga.transpose() * mu) * v
            + Matrix3::identity() * (mu * ga.dot(&gb) * v)
    }

    /// The 12×12 element stiffness matrix, DOFs ordered (vertex, component).
    pub fn stiffness(&self, material: &LinearElastic) -> SMatrix<f64, 12, 12> {
        let (lambda, mu) = (material.lame_lambda(), material.shear_modulus());
        let mut k = SMatrix::<f64, 12, 12>::zeros();
        for a in 0..4 {
            for b in 0..4 {
                k.fixed_view_mut::<3, 3>(3 * a, 3 * b)
                    .copy_from(&self.stiffness_block(a, b, lambda, mu));
            }
        }
        k
    }

    /// The consistent mass coefficient between vertices `a` and `b` (times I₃):
    /// ρV/20 · (1 + δ_ab).
    pub fn consistent_mass(&self, a: usize, b: usize, density: f64) -> f64 {
        let base = density * self.volume / 20.0;
        if a == b {
            2.0 * base
        } else {
            base
        }
    }

    /// The lumped (row-sum) mass of each vertex: ρV/4.
    pub fn lumped_mass(&self, density: f64) -> f64 {
        density * self.volume / 4.0
    }

    /// The (constant) small strain ε = sym(Σ u_a ⊗ ∇N_a) for vertex displacements `u`.
    pub fn strain(&self, u: [Vector3<f64>; 4]) -> Matrix3<f64> {
        let grad: Matrix3<f64> = (0..4).map(|a| u[a] * self.gradients[a].transpose()).sum();
        (grad + grad.transpose()) * 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn material() -> LinearElastic {
        LinearElastic {
            young_modulus: 45e9,
            poisson: 0.167,
            density: 2350.0,
        }
    }

    fn skewed_tet() -> TetGeometry {
        TetGeometry::new([
            Point3::new(0.1, -0.2, 0.05),
            Point3::new(1.3, 0.1, -0.1),
            Point3::new(0.2, 0.9, 0.3),
            Point3::new(0.4, 0.2, 1.1),
        ])
        .expect("valid tetra")
    }

    #[test]
    fn gradients_sum_to_zero_and_reproduce_linear_fields() {
        let x = [
            Point3::new(0.1, -0.2, 0.05),
            Point3::new(1.3, 0.1, -0.1),
            Point3::new(0.2, 0.9, 0.3),
            Point3::new(0.4, 0.2, 1.1),
        ];
        let tet = TetGeometry::new(x).unwrap();
        let sum: Vector3<f64> = tet.gradients.iter().sum();
        assert!(sum.norm() < 1e-12);
        // ∇ of the interpolant of f(x) = c·x is c.
        let c = Vector3::new(0.3, -1.7, 2.2);
        let grad: Vector3<f64> = (0..4).map(|a| tet.gradients[a] * c.dot(&x[a].coords)).sum();
        assert!((grad - c).norm() < 1e-12);
        let volume = (x[1] - x[0]).cross(&(x[2] - x[0])).dot(&(x[3] - x[0])) / 6.0;
        assert!((tet.volume - volume.abs()).abs() < 1e-15);
    }

    #[test]
    fn element_stiffness_is_symmetric_with_six_zero_eigenvalues() {
        let k = skewed_tet().stiffness(&material());
        let asym = (k - k.transpose()).abs().max();
        assert!(asym <= 1e-12 * k.abs().max(), "asymmetry {asym}");
        let mut eig: Vec<f64> = k.symmetric_eigenvalues().iter().copied().collect();
        eig.sort_by(f64::total_cmp);
        let largest = eig[11];
        for (i, &e) in eig.iter().enumerate() {
            if i < 6 {
                assert!(e.abs() < 1e-12 * largest, "eigenvalue {i} = {e}");
            } else {
                assert!(e > 1e-6 * largest, "eigenvalue {i} = {e}");
            }
        }
    }

    #[test]
    fn mass_sums_to_element_mass() {
        let tet = skewed_tet();
        let rho = 2350.0;
        let consistent: f64 = (0..4)
            .flat_map(|a| (0..4).map(move |b| (a, b)))
            .map(|(a, b)| tet.consistent_mass(a, b, rho))
            .sum();
        let mass = rho * tet.volume;
        assert!((consistent - mass).abs() < 1e-12 * mass);
        assert!((4.0 * tet.lumped_mass(rho) - mass).abs() < 1e-12 * mass);
    }

    #[test]
    fn degenerate_tetra_is_rejected() {
        let flat = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        assert!(TetGeometry::new(flat).is_none());
    }

    #[test]
    fn material_ranges_are_checked() {
        let mut m = material();
        assert!(m.check().is_ok());
        m.poisson = 0.5;
        assert!(m.check().unwrap_err().contains("poisson"));
    }
}
