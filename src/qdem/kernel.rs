//! The hot loop: eq. 1–10 for [`LANES`] tetra at once.
//!
//! The tetra are stored in batches of [`LANES`] in lane layout ([`TetBatch`]: every
//! reference quantity is a `[f64; LANES]`, so it loads straight into one vector
//! register). One batch is computed by [`batch_forces`], written once over the lane
//! types of [`crate::simd`] plus the gather and scatter of [`Gather`]:
//! - AVX2 + FMA: a vertex is gathered with a masked load (`[x, y, z, 0]`) and a 4 × 4
//!   transpose gives the x, y, z lanes; products are fused multiply-adds; the forces are
//!   transposed back and added to 32-byte node records ([`Force4`]) with one vector load
//!   and store; the batch stream is prefetched;
//! - portable: the same formulas on plain arrays, unfused.
//!
//! On one machine the forces are bitwise the same for any thread count (one path per
//! process, and the colouring fixes the summation order); both paths agree with the
//! scalar reference [`super::element::element_forces`] to round-off (tests below).

// Lane loops index several arrays by the same lane: that is the point (SIMD packing).
#![allow(clippy::needless_range_loop)]

use super::colouring::ForceTarget;
use super::element::{ElementSums, Mat3, Vec3};
use super::material::ElementMaterial;
use crate::simd::{F64x4, Portable4};
use std::ops::Range;

/// Tetra handed to the kernel at once (SIMD lanes).
pub(crate) const LANES: usize = 4;

/// A node's force in the hot loop: x, y, z and a zero pad, aligned to 32 bytes so that
/// one vector load and store update it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Force4(pub [f64; 4]);

impl Force4 {
    /// The x, y, z components.
    pub fn xyz(&self) -> Vec3 {
        [self.0[0], self.0[1], self.0[2]]
    }
}

/// [`LANES`] consecutive tetra (internal order) in lane layout. A batch at the end of
/// the mesh repeats its last tetra in the missing lanes (valid data, results dropped).
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub(crate) struct TetBatch {
    /// D_m⁻¹: `dm[k][c][lane]` (rows k are the reference gradients of N_1..N_3).
    pub dm: [[[f64; LANES]; 3]; 3],
    /// Reference volumes V_0 (m³).
    pub volume: [f64; LANES],
    /// `nodes[k][lane]`: vertex k of each tetra.
    pub nodes: [[u32; LANES]; 4],
    /// Material index of each tetra.
    pub material: [u32; LANES],
}

/// What one lane of a batch holds, as a single tetra.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TetElement {
    /// D_m⁻¹: rows are the reference gradients of N_1, N_2, N_3.
    pub dm_inv: Mat3,
    /// Reference volume V_0 (m³).
    pub ref_volume: f64,
    /// Index into the model's materials.
    pub material: u32,
}

impl TetBatch {
    /// Packs up to [`LANES`] tetra (`nodes[i]`, `elements[i]`), repeating the last.
    pub fn pack(nodes: &[[u32; 4]], elements: &[TetElement]) -> Self {
        assert!(!nodes.is_empty() && nodes.len() <= LANES && nodes.len() == elements.len());
        let mut b = TetBatch {
            dm: [[[0.0; LANES]; 3]; 3],
            volume: [0.0; LANES],
            nodes: [[0; LANES]; 4],
            material: [0; LANES],
        };
        for l in 0..LANES {
            let i = l.min(nodes.len() - 1);
            let el = &elements[i];
            for k in 0..3 {
                for c in 0..3 {
                    b.dm[k][c][l] = el.dm_inv[k][c];
                }
            }
            b.volume[l] = el.ref_volume;
            for k in 0..4 {
                b.nodes[k][l] = nodes[i][k];
            }
            b.material[l] = el.material;
        }
        b
    }

    /// The tetra in lane `l`.
    pub fn element(&self, l: usize) -> TetElement {
        TetElement {
            dm_inv: [0, 1, 2].map(|k| [0, 1, 2].map(|c| self.dm[k][c][l])),
            ref_volume: self.volume[l],
            material: self.material[l],
        }
    }
}

/// What the kernel reads besides the batches.
pub(crate) struct Inputs<'a> {
    /// Node positions.
    pub x: &'a [Vec3],
    /// Node velocities.
    pub v: &'a [Vec3],
    /// The tetra, [`LANES`] per batch.
    pub batches: &'a [TetBatch],
    /// Materials by index.
    pub materials: &'a [ElementMaterial],
}

/// Adds the internal forces of tetra `range` (internal order; `range.start` is a
/// multiple of [`LANES`]) to `target` at their nodes, and their energy terms to `sums`.
///
/// # Safety
/// Every node index of the batches is below `x.len() == v.len() == target`'s length,
/// and no other thread accesses the nodes of these tetra in `target` meanwhile.
pub(crate) unsafe fn block_forces(
    inputs: &Inputs<'_>,
    range: Range<usize>,
    target: &ForceTarget<'_, Force4>,
    sums: &mut ElementSums,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::simd::avx2_fma() {
            return avx::block_forces(inputs, range, target, sums);
        }
    }
    block_body::<Portable4>(inputs, range, target, sums)
}

#[inline(always)]
unsafe fn block_body<S: Gather>(
    inputs: &Inputs<'_>,
    range: Range<usize>,
    target: &ForceTarget<'_, Force4>,
    sums: &mut ElementSums,
) {
    debug_assert_eq!(range.start % LANES, 0);
    let mut first = range.start;
    while first < range.end {
        let count = LANES.min(range.end - first);
        S::prefetch(
            inputs
                .batches
                .as_ptr()
                .wrapping_add(first / LANES + PREFETCH_AHEAD),
        );
        batch_forces::<S>(inputs, &inputs.batches[first / LANES], count, target, sums);
        first += LANES;
    }
}

const PREFETCH_AHEAD: usize = 12;

/// The kernel's memory operations on a lane type.
trait Gather: F64x4 {
    /// Edge vectors `e[k][d]` = `p[nodes[k + 1]][d] − p[nodes[0]][d]` of each lane.
    /// Safety: the node indices are below `p.len()`.
    unsafe fn edges(p: &[Vec3], nodes: &[[u32; LANES]; 4]) -> [[Self; 3]; 3];
    /// Adds `f[k][d]` of lanes `0..count` to node `nodes[k][lane]` of `target`, lane by
    /// lane, vertex by vertex. Safety: as [`block_forces`].
    unsafe fn scatter(
        target: &ForceTarget<'_, Force4>,
        nodes: &[[u32; LANES]; 4],
        f: &[[Self; 3]; 4],
        count: usize,
    );
    /// Hints that the batch at `p` (possibly past the end: never dereferenced) is next.
    fn prefetch(_p: *const TetBatch) {}
}

/// The material constants of a batch as lanes.
struct Constants<S> {
    lambda: S,
    mu: S,
    lambda_d: S,
    mu_d: S,
    viscous: bool,
}

#[inline(always)]
fn constants<S: F64x4>(materials: &[ElementMaterial], index: &[u32; LANES]) -> Constants<S> {
    let first = &materials[index[0] as usize];
    if index[1..].iter().all(|&i| i == index[0]) {
        return Constants {
            lambda: S::splat(first.lambda),
            mu: S::splat(first.mu),
            lambda_d: S::splat(first.viscous_lambda),
            mu_d: S::splat(first.viscous_mu),
            viscous: first.viscous,
        };
    }
    let mut lanes = [[0.0; LANES]; 4];
    let mut viscous = false;
    for l in 0..LANES {
        let m = &materials[index[l] as usize];
        lanes[0][l] = m.lambda;
        lanes[1][l] = m.mu;
        lanes[2][l] = m.viscous_lambda;
        lanes[3][l] = m.viscous_mu;
        viscous |= m.viscous;
    }
    Constants {
        lambda: S::load(&lanes[0]),
        mu: S::load(&lanes[1]),
        lambda_d: S::load(&lanes[2]),
        mu_d: S::load(&lanes[3]),
        viscous,
    }
}

/// `a₀b₀ + a₁b₁ + a₂b₂` as two fused steps.
#[inline(always)]
fn dot3<S: F64x4>(a: [S; 3], b: [S; 3]) -> S {
    a[2].mul_add(b[2], a[1].mul_add(b[1], a[0] * b[0]))
}

/// a × c.
#[inline(always)]
fn cross<S: F64x4>(a: [S; 3], c: [S; 3]) -> [S; 3] {
    [
        a[1].mul_sub(c[2], a[2] * c[1]),
        a[2].mul_sub(c[0], a[0] * c[2]),
        a[0].mul_sub(c[1], a[1] * c[0]),
    ]
}

/// Symmetric (xx, yy, zz, xy, yz, zx) times a vector.
#[inline(always)]
fn sym_times<S: F64x4>(t: &[S; 6], g: [S; 3]) -> [S; 3] {
    [
        dot3([t[0], t[3], t[5]], g),
        dot3([t[3], t[1], t[4]], g),
        dot3([t[5], t[4], t[2]], g),
    ]
}

/// λ tr(a) I + 2µ a for a symmetric a.
#[inline(always)]
fn hooke<S: F64x4>(lambda: S, mu: S, a: &[S; 6]) -> [S; 6] {
    let two_mu = mu + mu;
    let lt = lambda * (a[0] + a[1] + a[2]);
    [
        two_mu.mul_add(a[0], lt),
        two_mu.mul_add(a[1], lt),
        two_mu.mul_add(a[2], lt),
        two_mu * a[3],
        two_mu * a[4],
        two_mu * a[5],
    ]
}

/// a : b for symmetric tensors (off-diagonal terms counted twice).
#[inline(always)]
fn contract<S: F64x4>(a: &[S; 6], b: &[S; 6]) -> S {
    let diagonal = dot3([a[0], a[1], a[2]], [b[0], b[1], b[2]]);
    let off = dot3([a[3], a[4], a[5]], [b[3], b[4], b[5]]);
    off.mul_add(S::splat(2.0), diagonal)
}

/// One batch: gather, eq. 1–10, scatter.
#[inline(always)]
unsafe fn batch_forces<S: Gather>(
    inputs: &Inputs<'_>,
    b: &TetBatch,
    count: usize,
    target: &ForceTarget<'_, Force4>,
    sums: &mut ElementSums,
) {
    let m = constants::<S>(inputs.materials, &b.material);
    let e = S::edges(inputs.x, &b.nodes);
    // Eq. 1: F = D_s D_m⁻¹ (columns of D_s are the edges).
    // (No closures or array maps on this path: they would not inherit the caller's
    // target features, and the intrinsics inside them would not be inlined.)
    let zero = S::splat(0.0);
    let mut f = [[zero; 3]; 3];
    for c in 0..3 {
        let dm = [
            S::load(&b.dm[0][c]),
            S::load(&b.dm[1][c]),
            S::load(&b.dm[2][c]),
        ];
        for r in 0..3 {
            f[r][c] = dot3([e[0][r], e[1][r], e[2][r]], dm);
        }
    }
    // Eq. 2–4: ε = (F Fᵀ − I)/2, T_E = λ tr ε I + 2µ ε; strain energy density ½ T_E : ε.
    let half = S::splat(0.5);
    let one = S::splat(1.0);
    let eps = [
        half * (dot3(f[0], f[0]) - one),
        half * (dot3(f[1], f[1]) - one),
        half * (dot3(f[2], f[2]) - one),
        half * dot3(f[0], f[1]),
        half * dot3(f[1], f[2]),
        half * dot3(f[2], f[0]),
    ];
    let mut t = hooke(m.lambda, m.mu, &eps);
    let energy = half * contract(&t, &eps);
    // Rows of adj(D_s): g_1 = e_2 × e_3, g_2 = e_3 × e_1, g_3 = e_1 × e_2; det D_s.
    let g = [cross(e[1], e[2]), cross(e[2], e[0]), cross(e[0], e[1])];
    let det = dot3(e[0], g[0]);
    let mut dissipation = zero;
    if m.viscous {
        // Eq. 5–7: L = (1/det) Σ_k (v_k − v_0) ⊗ g_k, D = sym L, T_D = λ_D tr D I + 2µ_D D.
        let dv = S::edges(inputs.v, &b.nodes);
        let inv = one / det;
        let mut l = [[zero; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                l[i][j] = dot3([dv[0][i], dv[1][i], dv[2][i]], [g[0][j], g[1][j], g[2][j]]);
            }
        }
        let d = [
            l[0][0] * inv,
            l[1][1] * inv,
            l[2][2] * inv,
            half * (l[0][1] + l[1][0]) * inv,
            half * (l[1][2] + l[2][1]) * inv,
            half * (l[2][0] + l[0][2]) * inv,
        ];
        let td = hooke(m.lambda_d, m.mu_d, &d);
        // T_D : D over the current volume det/6.
        dissipation = contract(&td, &d) * det * S::splat(1.0 / 6.0);
        // Eq. 8: T = T_E + T_D.
        for s in 0..6 {
            t[s] = t[s] + td[s];
        }
    }
    // Eq. 9–10 in closed form: f_k = −(1/6) T g_k, f_0 = −(f_1 + f_2 + f_3).
    let scale = S::splat(-1.0 / 6.0);
    let mut ts = t;
    for c in &mut ts {
        *c = *c * scale;
    }
    let f1 = sym_times(&ts, g[0]);
    let f2 = sym_times(&ts, g[1]);
    let f3 = sym_times(&ts, g[2]);
    let mut f0 = [zero; 3];
    for d in 0..3 {
        f0[d] = zero - (f1[d] + f2[d] + f3[d]);
    }
    S::scatter(target, &b.nodes, &[f0, f1, f2, f3], count);
    let energy = (energy * S::load(&b.volume)).to_array();
    let dissipation = dissipation.to_array();
    let det = det.to_array();
    for l in 0..count {
        sums.strain_energy += energy[l];
        sums.dissipation_rate += dissipation[l];
        if det[l].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            sums.inverted += 1;
        }
    }
}

impl Gather for Portable4 {
    #[inline(always)]
    unsafe fn edges(p: &[Vec3], nodes: &[[u32; LANES]; 4]) -> [[Self; 3]; 3] {
        let mut e = [[Portable4([0.0; LANES]); 3]; 3];
        for l in 0..LANES {
            let x0 = p[nodes[0][l] as usize];
            for k in 0..3 {
                let xk = p[nodes[k + 1][l] as usize];
                for d in 0..3 {
                    e[k][d].0[l] = xk[d] - x0[d];
                }
            }
        }
        e
    }
    #[inline(always)]
    unsafe fn scatter(
        target: &ForceTarget<'_, Force4>,
        nodes: &[[u32; LANES]; 4],
        f: &[[Self; 3]; 4],
        count: usize,
    ) {
        for l in 0..count {
            for k in 0..4 {
                let p = &mut *target.node(nodes[k][l] as usize);
                for d in 0..3 {
                    p.0[d] += f[k][d].0[l];
                }
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! The gather and scatter of the AVX2 + FMA lanes.
    use super::*;
    use crate::simd::avx::Avx4;
    use std::arch::x86_64::*;

    /// [`super::block_forces`] compiled for AVX2 + FMA.
    /// Safety: as [`super::block_forces`], and the CPU has AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn block_forces(
        inputs: &Inputs<'_>,
        range: Range<usize>,
        target: &ForceTarget<'_, Force4>,
        sums: &mut ElementSums,
    ) {
        block_body::<Avx4>(inputs, range, target, sums)
    }

    /// Rows `[x, y, z, _]` of four lanes → columns x, y, z.
    #[inline(always)]
    unsafe fn columns(r: [__m256d; 4]) -> [Avx4; 3] {
        let t0 = _mm256_unpacklo_pd(r[0], r[1]); // x0 x1 z0 z1
        let t1 = _mm256_unpackhi_pd(r[0], r[1]); // y0 y1 _ _
        let t2 = _mm256_unpacklo_pd(r[2], r[3]); // x2 x3 z2 z3
        let t3 = _mm256_unpackhi_pd(r[2], r[3]); // y2 y3 _ _
        [
            Avx4(_mm256_permute2f128_pd(t0, t2, 0x20)),
            Avx4(_mm256_permute2f128_pd(t1, t3, 0x20)),
            Avx4(_mm256_permute2f128_pd(t0, t2, 0x31)),
        ]
    }

    /// Columns x, y, z of four lanes → rows `[x, y, z, 0]`.
    #[inline(always)]
    unsafe fn rows(c: &[Avx4; 3]) -> [__m256d; 4] {
        let zero = _mm256_setzero_pd();
        let t0 = _mm256_unpacklo_pd(c[0].0, c[1].0); // x0 y0 x2 y2
        let t1 = _mm256_unpackhi_pd(c[0].0, c[1].0); // x1 y1 x3 y3
        let t2 = _mm256_unpacklo_pd(c[2].0, zero); // z0 0 z2 0
        let t3 = _mm256_unpackhi_pd(c[2].0, zero); // z1 0 z3 0
        [
            _mm256_permute2f128_pd(t0, t2, 0x20),
            _mm256_permute2f128_pd(t1, t3, 0x20),
            _mm256_permute2f128_pd(t0, t2, 0x31),
            _mm256_permute2f128_pd(t1, t3, 0x31),
        ]
    }

    impl Gather for Avx4 {
        #[inline(always)]
        unsafe fn edges(p: &[Vec3], nodes: &[[u32; LANES]; 4]) -> [[Self; 3]; 3] {
            let mask = _mm256_set_epi64x(0, -1, -1, -1);
            let base = p.as_ptr() as *const f64;
            let mut origin = [_mm256_setzero_pd(); 4];
            for l in 0..LANES {
                origin[l] = _mm256_maskload_pd(base.add(3 * nodes[0][l] as usize), mask);
            }
            let mut e = [[Avx4(_mm256_setzero_pd()); 3]; 3];
            for k in 0..3 {
                let mut r = [_mm256_setzero_pd(); 4];
                for l in 0..LANES {
                    let p = _mm256_maskload_pd(base.add(3 * nodes[k + 1][l] as usize), mask);
                    r[l] = _mm256_sub_pd(p, origin[l]);
                }
                e[k] = columns(r);
            }
            e
        }
        #[inline(always)]
        unsafe fn scatter(
            target: &ForceTarget<'_, Force4>,
            nodes: &[[u32; LANES]; 4],
            f: &[[Self; 3]; 4],
            count: usize,
        ) {
            let r = [rows(&f[0]), rows(&f[1]), rows(&f[2]), rows(&f[3])];
            for l in 0..count {
                for k in 0..4 {
                    let p = target.node(nodes[k][l] as usize) as *mut f64;
                    _mm256_store_pd(p, _mm256_add_pd(_mm256_load_pd(p), r[k][l]));
                }
            }
        }
        #[inline(always)]
        fn prefetch(p: *const TetBatch) {
            let p = p as *const i8;
            // SAFETY: a prefetch never faults, whatever the address.
            unsafe {
                for line in 0..(std::mem::size_of::<TetBatch>() / 64) {
                    _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::qdem::element::{element_forces, reference_inverse};
    use crate::qdem::material::QdemMaterial;

    /// Seven jittered tetra with alternating elastic and viscous materials, the batched
    /// kernel on every path against the scalar reference of eq. 1–10.
    #[test]
    fn batched_kernel_matches_the_scalar_one() {
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
            // Tetra 4..6 share one material: the uniform-batch branch.
            elements.push(TetElement {
                dm_inv,
                ref_volume,
                material: if t < 4 { t % 2 } else { 1 },
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
        let batches = [
            TetBatch::pack(&nodes[0..4], &elements[0..4]),
            TetBatch::pack(&nodes[4..7], &elements[4..7]),
        ];
        let inputs = Inputs {
            x: &x,
            v: &v,
            batches: &batches,
            materials: &materials,
        };
        let mut scalar_sums = ElementSums::default();
        let mut expected = vec![Force4::default(); x.len()];
        for (e, tet) in nodes.iter().enumerate() {
            let el = &elements[e];
            let f = element_forces(
                &tet.map(|i| x[i as usize]),
                &tet.map(|i| v[i as usize]),
                &el.dm_inv,
                el.ref_volume,
                &materials[el.material as usize],
                &mut scalar_sums,
            );
            for k in 0..4 {
                for d in 0..3 {
                    expected[tet[k] as usize].0[d] += f[k][d];
                }
            }
        }
        let check = |path: &str, run: &dyn Fn(&ForceTarget<'_, Force4>, &mut ElementSums)| {
            let mut forces = vec![Force4::default(); x.len()];
            let mut sums = ElementSums::default();
            run(&ForceTarget::new(&mut forces), &mut sums);
            for (n, (got, want)) in forces.iter().zip(&expected).enumerate() {
                let scale = want.0.iter().fold(0.0f64, |a, c| a.max(c.abs()));
                for d in 0..3 {
                    assert!(
                        (got.0[d] - want.0[d]).abs() <= 1e-12 * scale,
                        "{path}: node {n}: {:?} against {:?}",
                        got.0,
                        want.0
                    );
                }
                assert_eq!(got.0[3], 0.0);
            }
            let rel = |a: f64, b: f64| (a / b - 1.0).abs();
            assert!(
                rel(sums.strain_energy, scalar_sums.strain_energy) < 1e-12,
                "{path}"
            );
            assert!(
                rel(sums.dissipation_rate, scalar_sums.dissipation_rate) < 1e-12,
                "{path}"
            );
            assert_eq!(sums.inverted, 0);
        };
        check("portable", &|t, s| unsafe {
            block_body::<Portable4>(&inputs, 0..7, t, s)
        });
        check("dispatched", &|t, s| unsafe {
            block_forces(&inputs, 0..7, t, s)
        });
    }

    #[test]
    fn an_inverted_tetra_is_counted() {
        let reference = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let (dm_inv, ref_volume) = reference_inverse(reference).unwrap();
        let mut x = reference.to_vec();
        x[3][2] = -1.0; // vertex 3 through the opposite face
        let el = TetElement {
            dm_inv,
            ref_volume,
            material: 0,
        };
        let batches = [TetBatch::pack(&[[0, 1, 2, 3]], &[el])];
        let materials = [ElementMaterial::from(&QdemMaterial::elastic(
            2000.0, 1e9, 0.2,
        ))];
        let v = vec![[0.0; 3]; 4];
        let inputs = Inputs {
            x: &x,
            v: &v,
            batches: &batches,
            materials: &materials,
        };
        let mut forces = vec![Force4::default(); 4];
        let mut sums = ElementSums::default();
        unsafe { block_forces(&inputs, 0..1, &ForceTarget::new(&mut forces), &mut sums) };
        assert_eq!(sums.inverted, 1);
    }
}
