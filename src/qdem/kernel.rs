//! The hot loop: eq. 1–10 for [`LANES`] tetra at once, written lane-wise so that the
//! compiler packs the lanes into SIMD registers (AVX2 when the CPU has it, chosen at run
//! time; SSE2 otherwise). Same arithmetic, operation for operation, as
//! [`super::element::element_forces`] (no fused multiply-add), so every path gives
//! bitwise the same forces.

// Lane loops index several arrays by the same lane: that is the point (SIMD packing).
#![allow(clippy::needless_range_loop)]

use super::colouring::LANES;
use super::element::{ElementSums, Vec3};
use super::material::ElementMaterial;
use super::model::TetElement;

type Lanes = [f64; LANES];
type LaneMat = [[Lanes; 3]; 3];

/// Inputs of one batch.
pub(crate) struct Batch<'a> {
    pub x: &'a [Vec3],
    pub v: &'a [Vec3],
    pub nodes: &'a [[u32; 4]],
    pub elements: &'a [TetElement],
    pub materials: &'a [ElementMaterial],
}

/// Forces on the four vertices of tetra `first..first + count` (count ≤ LANES); the
/// energy terms of those tetra are added to `sums`.
pub(crate) fn forces(
    batch: &Batch<'_>,
    first: usize,
    count: usize,
    sums: &mut ElementSums,
) -> [[Vec3; 4]; LANES] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { forces_avx2(batch, first, count, sums) };
        }
    }
    forces_generic(batch, first, count, sums)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn forces_avx2(
    batch: &Batch<'_>,
    first: usize,
    count: usize,
    sums: &mut ElementSums,
) -> [[Vec3; 4]; LANES] {
    forces_generic(batch, first, count, sums)
}

#[inline(always)]
fn forces_generic(
    batch: &Batch<'_>,
    first: usize,
    count: usize,
    sums: &mut ElementSums,
) -> [[Vec3; 4]; LANES] {
    debug_assert!((1..=LANES).contains(&count));
    // Gather: edges e_k = x_k − x_0, D_m⁻¹, constants. Lanes past `count` repeat the
    // last tetra (valid data, results dropped).
    let mut e: LaneMat = [[[0.0; LANES]; 3]; 3]; // e[k][d][lane]
    let mut dm: LaneMat = [[[0.0; LANES]; 3]; 3]; // dm[k][c][lane]
    let mut volume = [0.0; LANES];
    let (mut lambda, mut mu) = ([0.0; LANES], [0.0; LANES]);
    let (mut lambda_d, mut mu_d) = ([0.0; LANES], [0.0; LANES]);
    let mut viscous = false;
    for l in 0..LANES {
        let i = first + l.min(count - 1);
        let tet = batch.nodes[i];
        let x0 = batch.x[tet[0] as usize];
        for k in 0..3 {
            let xk = batch.x[tet[k + 1] as usize];
            for d in 0..3 {
                e[k][d][l] = xk[d] - x0[d];
            }
        }
        let el = &batch.elements[i];
        for k in 0..3 {
            for c in 0..3 {
                dm[k][c][l] = el.dm_inv[k][c];
            }
        }
        volume[l] = el.ref_volume;
        let m = &batch.materials[el.material as usize];
        lambda[l] = m.lambda;
        mu[l] = m.mu;
        lambda_d[l] = m.viscous_lambda;
        mu_d[l] = m.viscous_mu;
        viscous |= m.viscous;
    }
    // Eq. 1: F = D_s D_m⁻¹.
    let mut f: LaneMat = [[[0.0; LANES]; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            for l in 0..LANES {
                f[r][c][l] =
                    e[0][r][l] * dm[0][c][l] + e[1][r][l] * dm[1][c][l] + e[2][r][l] * dm[2][c][l];
            }
        }
    }
    // Eq. 2–4: ε = (F Fᵀ − I)/2, T_E = λ tr ε I + 2µ ε; strain energy density.
    let mut t = [[0.0; LANES]; 6];
    let mut energy = [0.0; LANES];
    {
        let pairs = [(0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0)];
        let mut eps = [[0.0; LANES]; 6];
        for (s, &(i, j)) in pairs.iter().enumerate() {
            let diagonal = if i == j { 1.0 } else { 0.0 };
            for l in 0..LANES {
                let b = f[i][0][l] * f[j][0][l] + f[i][1][l] * f[j][1][l] + f[i][2][l] * f[j][2][l];
                eps[s][l] = 0.5 * (b - diagonal);
            }
        }
        for l in 0..LANES {
            let tr = eps[0][l] + eps[1][l] + eps[2][l];
            let two_mu = 2.0 * mu[l];
            for s in 0..3 {
                t[s][l] = lambda[l] * tr + two_mu * eps[s][l];
            }
            for s in 3..6 {
                t[s][l] = two_mu * eps[s][l];
            }
            energy[l] = 0.5 * lambda[l] * tr * tr
                + mu[l]
                    * (eps[0][l] * eps[0][l]
                        + eps[1][l] * eps[1][l]
                        + eps[2][l] * eps[2][l]
                        + 2.0
                            * (eps[3][l] * eps[3][l]
                                + eps[4][l] * eps[4][l]
                                + eps[5][l] * eps[5][l]));
        }
    }
    // Rows of adj(D_s): g_1 = e_2 × e_3, g_2 = e_3 × e_1, g_3 = e_1 × e_2; det D_s.
    let mut g: LaneMat = [[[0.0; LANES]; 3]; 3];
    for (k, (a, b)) in [(1, 2), (2, 0), (0, 1)].into_iter().enumerate() {
        for l in 0..LANES {
            g[k][0][l] = e[a][1][l] * e[b][2][l] - e[a][2][l] * e[b][1][l];
            g[k][1][l] = e[a][2][l] * e[b][0][l] - e[a][0][l] * e[b][2][l];
            g[k][2][l] = e[a][0][l] * e[b][1][l] - e[a][1][l] * e[b][0][l];
        }
    }
    let mut det = [0.0; LANES];
    for l in 0..LANES {
        det[l] = e[0][0][l] * g[0][0][l] + e[0][1][l] * g[0][1][l] + e[0][2][l] * g[0][2][l];
    }
    let mut dissipation = [0.0; LANES];
    if viscous {
        // Eq. 5–7: L = (1/det) Σ_k (v_k − v_0) ⊗ g_k, D = sym L, T_D = λ_D tr D I + 2µ_D D.
        let mut dv: LaneMat = [[[0.0; LANES]; 3]; 3];
        for l in 0..LANES {
            let tet = batch.nodes[first + l.min(count - 1)];
            let v0 = batch.v[tet[0] as usize];
            for k in 0..3 {
                let vk = batch.v[tet[k + 1] as usize];
                for d in 0..3 {
                    dv[k][d][l] = vk[d] - v0[d];
                }
            }
        }
        let mut lm: LaneMat = [[[0.0; LANES]; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                for l in 0..LANES {
                    lm[i][j][l] = (dv[0][i][l] * g[0][j][l]
                        + dv[1][i][l] * g[1][j][l]
                        + dv[2][i][l] * g[2][j][l])
                        * (1.0 / det[l]);
                }
            }
        }
        for l in 0..LANES {
            let d = [
                lm[0][0][l],
                lm[1][1][l],
                lm[2][2][l],
                0.5 * (lm[0][1][l] + lm[1][0][l]),
                0.5 * (lm[1][2][l] + lm[2][1][l]),
                0.5 * (lm[2][0][l] + lm[0][2][l]),
            ];
            let tr_d = d[0] + d[1] + d[2];
            let two_mu_d = 2.0 * mu_d[l];
            let mut td = [0.0; 6];
            for s in 0..3 {
                td[s] = lambda_d[l] * tr_d + two_mu_d * d[s];
            }
            for s in 3..6 {
                td[s] = two_mu_d * d[s];
            }
            let density = td[0] * d[0]
                + td[1] * d[1]
                + td[2] * d[2]
                + 2.0 * (td[3] * d[3] + td[4] * d[4] + td[5] * d[5]);
            dissipation[l] = density * det[l] / 6.0;
            // Eq. 8: T = T_E + T_D.
            for s in 0..6 {
                t[s][l] += td[s];
            }
        }
    }
    // Eq. 9–10 in closed form: f_k = −(1/6) T g_k, f_0 = −(f_1 + f_2 + f_3).
    let mut out = [[[0.0; 3]; 4]; LANES];
    for l in 0..LANES {
        let (txx, tyy, tzz, txy, tyz, tzx) = (t[0][l], t[1][l], t[2][l], t[3][l], t[4][l], t[5][l]);
        let s = -1.0 / 6.0;
        let mut f0 = [0.0; 3];
        for k in 0..3 {
            let (g0, g1, g2) = (g[k][0][l], g[k][1][l], g[k][2][l]);
            let fk = [
                s * (txx * g0 + txy * g1 + tzx * g2),
                s * (txy * g0 + tyy * g1 + tyz * g2),
                s * (tzx * g0 + tyz * g1 + tzz * g2),
            ];
            out[l][k + 1] = fk;
            for d in 0..3 {
                f0[d] -= fk[d];
            }
        }
        out[l][0] = f0;
    }
    for l in 0..count {
        sums.strain_energy += energy[l] * volume[l];
        sums.dissipation_rate += dissipation[l];
        if det[l].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            sums.inverted += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qdem::element::{element_forces, reference_inverse};
    use crate::qdem::material::QdemMaterial;

    #[test]
    fn batched_kernel_matches_the_scalar_one_bitwise() {
        let mut seed = 1u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let materials = [
            ElementMaterial::from(&QdemMaterial::elastic(2000.0, 1e9, 0.2)),
            ElementMaterial::from(&QdemMaterial {
                shear_viscosity: 1e5,
                bulk_viscosity: 3e4,
                ..QdemMaterial::elastic(2500.0, 3e9, 0.3)
            }),
        ];
        // Seven separate unit-ish tetra, jittered; materials alternate.
        let mut x = Vec::new();
        let mut nodes = Vec::new();
        let mut elements = Vec::new();
        for t in 0..7u32 {
            let reference = [
                [0.0, 0.0, 0.0],
                [1.0, 0.1, 0.0],
                [0.2, 1.0, 0.1],
                [0.1, 0.2, 1.0],
            ];
            let (dm_inv, ref_volume) = reference_inverse(reference).unwrap();
            elements.push(TetElement {
                dm_inv,
                ref_volume,
                material: t % 2,
            });
            nodes.push([0, 1, 2, 3].map(|k| 4 * t + k));
            for p in reference {
                x.push([
                    p[0] + 0.05 * rnd(),
                    p[1] + 0.05 * rnd(),
                    p[2] + 0.05 * rnd(),
                ]);
            }
        }
        let v: Vec<Vec3> = x.iter().map(|_| [rnd(), rnd(), rnd()]).collect();
        let batch = Batch {
            x: &x,
            v: &v,
            nodes: &nodes,
            elements: &elements,
            materials: &materials,
        };
        let mut batched = ElementSums::default();
        let mut scalar = ElementSums::default();
        for (first, count) in [(0, 4), (4, 3)] {
            let out = forces(&batch, first, count, &mut batched);
            for lane in 0..count {
                let e = first + lane;
                let xe = nodes[e].map(|i| x[i as usize]);
                let ve = nodes[e].map(|i| v[i as usize]);
                let el = &elements[e];
                let f = element_forces(
                    &xe,
                    &ve,
                    &el.dm_inv,
                    el.ref_volume,
                    &materials[el.material as usize],
                    &mut scalar,
                );
                assert_eq!(out[lane], f, "tetra {e}");
            }
        }
        assert!((batched.strain_energy / scalar.strain_energy - 1.0).abs() < 1e-14);
        assert!((batched.dissipation_rate / scalar.dissipation_rate - 1.0).abs() < 1e-14);
    }
}
