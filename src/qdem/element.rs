//! The four-particle element of seed 004 §2: stress from the four vertices (eq. 1–8) and
//! nodal forces from the twelve equal-volume sub-surfaces (eq. 9–10, Figure 1a).
//!
//! Hot-loop form. For the current edge vectors e_k = x_k − x_0 (k = 1, 2, 3), the
//! sub-surfaces of vertex k (its six internal triangles) have a total outward area vector
//! equal to a third of the face opposite k, i.e. (1/6)·g_k with g_1 = e_2 × e_3,
//! g_2 = e_3 × e_1, g_3 = e_1 × e_2 (rows of adj(D_s) = det(D_s) D_s⁻¹). Eq. 9–10 summed
//! over a vertex's triangles therefore give f_k = −(1/6) T g_k = −V T ∇N_k: the standard
//! linear-tetra internal force in the current configuration. [`subsurface_forces`] builds
//! the twelve triangles literally, and a test checks both agree to round-off.

use super::material::ElementMaterial;
use nalgebra::{Matrix3, Point3, Vector3};

/// A 3-vector in the hot loop.
pub(crate) type Vec3 = [f64; 3];
/// A 3 × 3 matrix in the hot loop, row-major (`m[row][column]`).
pub(crate) type Mat3 = [[f64; 3]; 3];

#[inline(always)]
pub(crate) fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
pub(crate) fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
pub(crate) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// A symmetric tensor as (xx, yy, zz, xy, yz, zx).
pub(crate) type Sym3 = [f64; 6];

/// The symmetric tensor applied to a vector.
#[inline(always)]
pub(crate) fn sym_mul(t: &Sym3, g: Vec3) -> Vec3 {
    [
        t[0] * g[0] + t[3] * g[1] + t[5] * g[2],
        t[3] * g[0] + t[1] * g[1] + t[4] * g[2],
        t[5] * g[0] + t[4] * g[1] + t[2] * g[2],
    ]
}

/// Reference data of one tetra: D_m⁻¹ (rows = reference gradients of N_1..N_3) and V_0.
/// `None` for a flat or inverted tetra (non-positive volume).
pub(crate) fn reference_inverse(x: [Vec3; 4]) -> Option<(Mat3, f64)> {
    let e1 = sub(x[1], x[0]);
    let e2 = sub(x[2], x[0]);
    let e3 = sub(x[3], x[0]);
    let g1 = cross(e2, e3);
    let det = dot(e1, g1);
    if !(det > 0.0 && det.is_finite()) {
        return None;
    }
    let g2 = cross(e3, e1);
    let g3 = cross(e1, e2);
    let inv = 1.0 / det;
    let row = |g: Vec3| [g[0] * inv, g[1] * inv, g[2] * inv];
    Some(([row(g1), row(g2), row(g3)], det / 6.0))
}

/// What the kernel returns for one tetra besides its forces.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ElementSums {
    /// Strain energy V_0 (λ/2 (tr ε)² + µ ε:ε) in J.
    pub strain_energy: f64,
    /// Viscous dissipation rate V T_D : D in W.
    pub dissipation_rate: f64,
    /// Tetra whose current volume is not positive (inverted: the run is broken).
    pub inverted: u32,
}

/// Everything eq. 1–8 give for one tetra in its current state.
#[derive(Debug, Clone, Copy)]
#[cfg_attr(not(test), allow(dead_code))] // all read by the scalar reference kernel
pub(crate) struct ElementStress {
    /// Elastic Cauchy stress T_E (eq. 2).
    pub elastic: Sym3,
    /// Viscous Cauchy stress T_D (eq. 7); zero for an elastic material.
    pub viscous: Sym3,
    /// Strain energy density λ/2 (tr ε)² + µ ε:ε per unit reference volume (J/m³).
    pub energy_density: f64,
    /// T_D : D (W/m³ of current volume).
    pub dissipation_density: f64,
    /// Rows of adj(D_s): det(D_s) times the current gradients of N_1, N_2, N_3.
    pub adjugate: [Vec3; 3],
    /// det(D_s) = 6 × the current volume.
    pub det: f64,
}

/// Stress of one tetra from its current vertex positions and velocities: eq. 1–8.
#[inline(always)]
pub(crate) fn element_stress(
    x: &[Vec3; 4],
    v: &[Vec3; 4],
    dm_inv: &Mat3,
    m: &ElementMaterial,
) -> ElementStress {
    // Eq. 1: F = D_s D_m⁻¹, with D_s the current edge matrix (columns e_k).
    let e = [sub(x[1], x[0]), sub(x[2], x[0]), sub(x[3], x[0])];
    let mut f = [[0.0; 3]; 3];
    for (r, fr) in f.iter_mut().enumerate() {
        for (c, frc) in fr.iter_mut().enumerate() {
            *frc = e[0][r] * dm_inv[0][c] + e[1][r] * dm_inv[1][c] + e[2][r] * dm_inv[2][c];
        }
    }
    // Eq. 4: B = F Fᵀ (left Cauchy–Green); ε = (B − I)/2; eq. 2: T_E = λ tr ε I + 2µ ε.
    let b = |i: usize, j: usize| f[i][0] * f[j][0] + f[i][1] * f[j][1] + f[i][2] * f[j][2];
    let eps = [
        0.5 * (b(0, 0) - 1.0),
        0.5 * (b(1, 1) - 1.0),
        0.5 * (b(2, 2) - 1.0),
        0.5 * b(0, 1),
        0.5 * b(1, 2),
        0.5 * b(2, 0),
    ];
    let tr = eps[0] + eps[1] + eps[2];
    let two_mu = 2.0 * m.mu;
    let t_e = [
        m.lambda * tr + two_mu * eps[0],
        m.lambda * tr + two_mu * eps[1],
        m.lambda * tr + two_mu * eps[2],
        two_mu * eps[3],
        two_mu * eps[4],
        two_mu * eps[5],
    ];
    // Rows of adj(D_s) = det D_s · D_s⁻¹ (current gradients of N_1..N_3 times det).
    let g = [cross(e[1], e[2]), cross(e[2], e[0]), cross(e[0], e[1])];
    let det = dot(e[0], g[0]);
    let energy_density = 0.5 * m.lambda * tr * tr
        + m.mu
            * (eps[0] * eps[0]
                + eps[1] * eps[1]
                + eps[2] * eps[2]
                + 2.0 * (eps[3] * eps[3] + eps[4] * eps[4] + eps[5] * eps[5]));
    let mut t_d = [0.0; 6];
    let mut dissipation_density = 0.0;
    if m.viscous {
        // Eq. 5: L = D_v D_s⁻¹ = (1/det) Σ_k (v_k − v_0) ⊗ g_k; eq. 6: D = sym L.
        let dv = [sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0])];
        let inv = 1.0 / det;
        let l = |i: usize, j: usize| {
            (dv[0][i] * g[0][j] + dv[1][i] * g[1][j] + dv[2][i] * g[2][j]) * inv
        };
        let d = [
            l(0, 0),
            l(1, 1),
            l(2, 2),
            0.5 * (l(0, 1) + l(1, 0)),
            0.5 * (l(1, 2) + l(2, 1)),
            0.5 * (l(2, 0) + l(0, 2)),
        ];
        // Eq. 7: T_D = λ_D tr D I + 2µ_D D.
        let tr_d = d[0] + d[1] + d[2];
        let two_mu_d = 2.0 * m.viscous_mu;
        t_d = [
            m.viscous_lambda * tr_d + two_mu_d * d[0],
            m.viscous_lambda * tr_d + two_mu_d * d[1],
            m.viscous_lambda * tr_d + two_mu_d * d[2],
            two_mu_d * d[3],
            two_mu_d * d[4],
            two_mu_d * d[5],
        ];
        dissipation_density = t_d[0] * d[0]
            + t_d[1] * d[1]
            + t_d[2] * d[2]
            + 2.0 * (t_d[3] * d[3] + t_d[4] * d[4] + t_d[5] * d[5]);
    }
    ElementStress {
        elastic: t_e,
        viscous: t_d,
        energy_density,
        dissipation_density,
        adjugate: g,
        det,
    }
}

/// One tetra's eq. 1–8 for the stress and eq. 9–10 (in closed form, see the module
/// note) for the four nodal forces; adds the energy terms to `sums`. The scalar
/// reference of the batched hot loop ([`super::kernel`]), which must match it bit for
/// bit (tested).
#[cfg(test)]
pub(crate) fn element_forces(
    x: &[Vec3; 4],
    v: &[Vec3; 4],
    dm_inv: &Mat3,
    ref_volume: f64,
    m: &ElementMaterial,
    sums: &mut ElementSums,
) -> [Vec3; 4] {
    let st = element_stress(x, v, dm_inv, m);
    let (t_e, t_d, g, det) = (st.elastic, st.viscous, st.adjugate, st.det);
    sums.strain_energy += st.energy_density * ref_volume;
    if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        sums.inverted += 1;
    }
    let t = if m.viscous {
        // Eq. 8: T = T_E + T_D.
        sums.dissipation_rate += st.dissipation_density * det / 6.0;
        [
            t_e[0] + t_d[0],
            t_e[1] + t_d[1],
            t_e[2] + t_d[2],
            t_e[3] + t_d[3],
            t_e[4] + t_d[4],
            t_e[5] + t_d[5],
        ]
    } else {
        t_e
    };
    // Eq. 9–10 summed per vertex: f_k = −(1/6) T g_k, and f_0 = −(f_1 + f_2 + f_3).
    let s = -1.0 / 6.0;
    let f1 = sym_mul(&t, g[0]);
    let f2 = sym_mul(&t, g[1]);
    let f3 = sym_mul(&t, g[2]);
    let f1 = [s * f1[0], s * f1[1], s * f1[2]];
    let f2 = [s * f2[0], s * f2[1], s * f2[2]];
    let f3 = [s * f3[0], s * f3[1], s * f3[2]];
    let f0 = [
        -(f1[0] + f2[0] + f3[0]),
        -(f1[1] + f2[1] + f3[1]),
        -(f1[2] + f2[2] + f3[2]),
    ];
    [f0, f1, f2, f3]
}

/// A symmetric hot-loop tensor as an nalgebra matrix.
pub(crate) fn sym_to_matrix(t: &Sym3) -> Matrix3<f64> {
    Matrix3::new(t[0], t[3], t[5], t[3], t[1], t[4], t[5], t[4], t[2])
}

/// Eq. 9–10 taken literally: the forces on the four particles of one tetra from a
/// homogeneous Cauchy stress `stress` acting on the twelve triangles of Figure 1a in the
/// configuration `x` (the current one during a run).
///
/// For each edge jk (other vertices l, m) the triangles ⟨ec_jk, fc_jkl, fc_jkm⟩ and
/// ⟨vc, fc_jkl, fc_jkm⟩ separate the sub-domains of particles j and k. The stress vector
/// on a triangle with area vector S n (eq. 9: f_i = ½ T (a_i × b_i)), n oriented from j's
/// side towards k's, is the force that k's side exerts on j's sub-domain; k receives its
/// opposite (eq. 10 sums them per sub-domain). The paper's wording of the normal's sense
/// is ambiguous; this one is fixed by requiring that a stretched tetra pull its particles
/// back (and it reproduces −V T ∇N exactly).
pub fn subsurface_forces(x: &[Point3<f64>; 4], stress: &Matrix3<f64>) -> [Vector3<f64>; 4] {
    let vc = (x[0].coords + x[1].coords + x[2].coords + x[3].coords) / 4.0;
    let fc = |a: usize, b: usize, c: usize| (x[a].coords + x[b].coords + x[c].coords) / 3.0;
    let mut forces = [Vector3::zeros(); 4];
    for j in 0..4 {
        for k in (j + 1)..4 {
            let others: Vec<usize> = (0..4).filter(|&i| i != j && i != k).collect();
            let (l, m) = (others[0], others[1]);
            let ec = (x[j].coords + x[k].coords) / 2.0;
            let fl = fc(j, k, l);
            let fm = fc(j, k, m);
            let direction = x[k] - x[j];
            for apex in [ec, vc] {
                // Eq. 9 with a = fl − apex, b = fm − apex.
                let mut area = 0.5 * (fl - apex).cross(&(fm - apex));
                if area.dot(&direction) < 0.0 {
                    area = -area;
                }
                let f = stress * area;
                forces[j] += f;
                forces[k] -= f;
            }
        }
    }
    forces
}

/// The standard linear-tetra internal forces −V T ∇N_a in configuration `x` (the
/// reference for [`subsurface_forces`]).
pub fn linear_tetra_forces(x: &[Point3<f64>; 4], stress: &Matrix3<f64>) -> [Vector3<f64>; 4] {
    let ds = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
    let volume = ds.determinant() / 6.0;
    let inv = ds.try_inverse().unwrap_or_else(Matrix3::zeros);
    let mut forces = [Vector3::zeros(); 4];
    for k in 0..3 {
        let grad = inv.row(k).transpose();
        forces[k + 1] = -volume * stress * grad;
    }
    forces[0] = -(forces[1] + forces[2] + forces[3]);
    forces
}

/// The von Mises equivalent stress √(3/2 s:s) of a Cauchy stress (s its deviator), in Pa.
pub fn von_mises(stress: &Matrix3<f64>) -> f64 {
    let mean = stress.trace() / 3.0;
    let s = stress - Matrix3::identity() * mean;
    (1.5 * s.component_mul(&s).sum()).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qdem::material::QdemMaterial;

    /// Deterministic pseudo-random numbers in [−1, 1) (splitmix64).
    pub(crate) fn random(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *seed;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn random_tetra(seed: &mut u64) -> [Point3<f64>; 4] {
        loop {
            let mut p = [Point3::origin(); 4];
            for q in p.iter_mut() {
                *q = Point3::new(random(seed), random(seed), random(seed));
            }
            let v = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0]));
            if v.abs() > 0.05 {
                if v < 0.0 {
                    p.swap(2, 3);
                }
                return p;
            }
        }
    }

    #[test]
    fn subsurface_forces_equal_linear_tetra_forces() {
        let mut seed = 7u64;
        for _ in 0..200 {
            let x0 = random_tetra(&mut seed);
            // A random deformation gradient near identity (some large) applied to x0.
            let mut f = Matrix3::identity();
            for v in f.iter_mut() {
                *v += 0.4 * random(&mut seed);
            }
            if f.determinant() <= 0.1 {
                continue;
            }
            let x = x0.map(|p| Point3::from(f * p.coords));
            let mut t = Matrix3::zeros();
            for i in 0..3 {
                for j in i..3 {
                    let s = 1e6 * random(&mut seed);
                    t[(i, j)] = s;
                    t[(j, i)] = s;
                }
            }
            let a = subsurface_forces(&x, &t);
            let b = linear_tetra_forces(&x, &t);
            let scale = a.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for k in 0..4 {
                assert!(
                    (a[k] - b[k]).norm() <= 1e-12 * scale,
                    "vertex {k}: {:?} vs {:?}",
                    a[k],
                    b[k]
                );
            }
        }
    }

    #[test]
    fn kernel_forces_equal_subsurface_forces() {
        let mut seed = 11u64;
        let m = QdemMaterial {
            shear_viscosity: 3e3,
            bulk_viscosity: 1e3,
            ..QdemMaterial::elastic(2000.0, 1e7, 0.3)
        };
        let em = ElementMaterial::from(&m);
        for _ in 0..100 {
            let x0 = random_tetra(&mut seed);
            let xr = x0.map(|p| [p.x, p.y, p.z]);
            let (dm_inv, vol) = reference_inverse(xr).unwrap();
            let mut x = xr;
            let mut v = [[0.0; 3]; 4];
            for k in 0..4 {
                for d in 0..3 {
                    x[k][d] += 0.05 * random(&mut seed);
                    v[k][d] = random(&mut seed);
                }
            }
            if reference_inverse(x).is_none() {
                continue; // the perturbation inverted a thin tetra
            }
            let mut sums = ElementSums::default();
            let f = element_forces(&x, &v, &dm_inv, vol, &em, &mut sums);
            let st = element_stress(&x, &v, &dm_inv, &em);
            let t_d = st.viscous;
            let t = sym_to_matrix(&st.elastic) + sym_to_matrix(&t_d);
            let xp = x.map(|p| Point3::new(p[0], p[1], p[2]));
            let reference = subsurface_forces(&xp, &t);
            let scale = reference.iter().map(|v| v.norm()).fold(0.0, f64::max);
            for k in 0..4 {
                let d = Vector3::from(f[k]) - reference[k];
                assert!(d.norm() <= 1e-12 * scale, "vertex {k}");
            }
            // Dissipation rate equals V T_D : D with D recomputed directly.
            let ds = Matrix3::from_columns(&[xp[1] - xp[0], xp[2] - xp[0], xp[3] - xp[0]]);
            let dvm = Matrix3::from_fn(|i, j| v[j + 1][i] - v[0][i]);
            let l = dvm * ds.try_inverse().unwrap();
            let d = (l + l.transpose()) / 2.0;
            let power = sym_to_matrix(&t_d).component_mul(&d).sum() * ds.determinant() / 6.0;
            assert!((sums.dissipation_rate - power).abs() <= 1e-9 * power.abs().max(1e-30));
        }
    }

    #[test]
    fn subdomains_have_equal_volumes() {
        // Volume of particle j's sub-domain by the divergence theorem over its boundary:
        // its six internal triangles and the three quadrilaterals it owns on the faces.
        let mut seed = 5u64;
        let x = random_tetra(&mut seed);
        let c = |ps: &[Vector3<f64>]| ps.iter().sum::<Vector3<f64>>() / ps.len() as f64;
        let vc = c(&x.map(|p| p.coords));
        let total = (x[1] - x[0]).cross(&(x[2] - x[0])).dot(&(x[3] - x[0])) / 6.0;
        for j in 0..4 {
            let mut volume = 0.0;
            // A flat polygon's contribution: (1/3) centroid · area vector (outward).
            let mut add = |pts: &[Vector3<f64>], outward_hint: Vector3<f64>| {
                let mut area = Vector3::zeros();
                for i in 1..pts.len() - 1 {
                    area += 0.5 * (pts[i] - pts[0]).cross(&(pts[i + 1] - pts[0]));
                }
                if area.dot(&outward_hint) < 0.0 {
                    area = -area;
                }
                volume += c(pts).dot(&area) / 3.0;
            };
            for k in (0..4).filter(|&k| k != j) {
                let o: Vec<usize> = (0..4).filter(|&i| i != j && i != k).collect();
                let ec = (x[j].coords + x[k].coords) / 2.0;
                let fl = (x[j].coords + x[k].coords + x[o[0]].coords) / 3.0;
                let fm = (x[j].coords + x[k].coords + x[o[1]].coords) / 3.0;
                add(&[ec, fl, fm], x[k] - x[j]);
                add(&[vc, fl, fm], x[k] - x[j]);
            }
            for (a, b) in [(1, 2), (1, 3), (2, 3)] {
                let others: Vec<usize> = (0..4).filter(|&i| i != j).collect();
                let (k, l) = (others[a - 1], others[b - 1]);
                let m = 6 - j - k - l;
                let quad = [
                    x[j].coords,
                    (x[j].coords + x[k].coords) / 2.0,
                    (x[j].coords + x[k].coords + x[l].coords) / 3.0,
                    (x[j].coords + x[l].coords) / 2.0,
                ];
                add(&quad, x[j] - x[m]);
            }
            assert!(
                (volume / total - 0.25).abs() < 1e-12,
                "particle {j}: {volume}"
            );
        }
    }

    #[test]
    fn von_mises_of_uniaxial_stress_is_the_stress() {
        let t = Matrix3::new(5.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!((von_mises(&t) - 5.0).abs() < 1e-14);
    }
}
