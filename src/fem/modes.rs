//! Lowest eigenpairs of K φ = ω² M φ by shift-invert block Lanczos.
//!
//! With a shift σ below the wanted eigenvalues, A = (K − σM)⁻¹ M is self-adjoint in the
//! M inner product and its largest eigenvalues θ = 1/(λ − σ) belong to the lowest λ.
//! K − σM is factorised once (sparse Cholesky on the system's symbolic factor; for
//! σ = 0 the factor of K from the static solve is reused).
//!
//! Each step is one block solve: A is applied to the newest block of the basis V, which
//! is kept M-orthonormal (block classical Gram–Schmidt twice, then orthonormalisation
//! by the eigenvectors of the block's Gram matrix, dropping directions within 1e-10 of
//! the basis). Rayleigh–Ritz on H = (MV)ᵀ A V gives Ritz pairs (θ, φ = V s); the next
//! block is the residuals (I − V (MV)ᵀ) A V s of the unconverged lowest pairs, which
//! spans the next block Krylov space. When the basis is full it restarts thick, keeping
//! the lowest Ritz vectors with their A V. A pair is converged when
//! ‖(I − V (MV)ᵀ) A φ‖ ≤ tol · θ ‖φ‖: ARPACK's shift-invert test, taken orthogonal to
//! the basis so that solve errors along basis vectors (the rigid modes of a free body
//! under a small negative shift) do not count. No dense eigen-solve of the full size is
//! ever made; the projected problems are at most `max_basis` wide.

use super::cholesky::Factor;
use super::{seconds_since, FemSystem, PhaseTimes};
use crate::{Error, Result};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::{DMatrix, SymmetricEigen, Vector3};
use std::time::Instant;

/// Which mass matrix the modes use.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum MassKind {
    /// The consistent mass matrix (as CalculiX uses for frequencies).
    #[default]
    Consistent,
    /// Row-sum lumped (diagonal) mass, ρV/4 per vertex.
    Lumped,
}

/// The spectral shift σ in (rad/s)².
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum Shift {
    /// σ = 0 when the supports remove every rigid-body motion (the static factor of K
    /// is reused), otherwise a small negative shift, −1e-8 × the mean of diag K / diag M
    /// (K − σM is then positive definite, rigid modes come out at ≈ 0 Hz).
    #[default]
    Auto,
    /// A given σ; it must lie below the lowest eigenvalue (K − σM positive definite).
    Value(f64),
}

/// Options of the eigensolver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModeOptions {
    /// The shift σ.
    pub shift: Shift,
    /// Convergence tolerance on the residual angle of each pair (see the module docs).
    pub tol: f64,
    /// The most block steps (each one block solve with the factorised shifted matrix).
    pub max_iter: usize,
    /// Consistent (default) or lumped mass.
    pub mass: MassKind,
    /// Vectors per block (at least k are used); default max(k, 6) (six covers the
    /// rigid modes of a free body).
    pub block_size: Option<usize>,
    /// Largest basis before a thick restart; default max(2k + 4·block, 24).
    pub max_basis: Option<usize>,
    /// Seed of the (deterministic) random start block.
    pub seed: u64,
}

impl Default for ModeOptions {
    fn default() -> Self {
        ModeOptions {
            shift: Shift::Auto,
            tol: 1e-8,
            max_iter: 200,
            mass: MassKind::Consistent,
            block_size: None,
            max_basis: None,
            seed: 0x5eed_ba11_a570,
        }
    }
}

/// The lowest modes, in ascending order.
#[derive(Debug, Clone)]
pub struct Modes {
    /// ω² in (rad/s)²; rigid modes give values near zero of either sign.
    pub eigenvalues: Vec<f64>,
    /// sign(ω²) · √|ω²| / 2π in Hz.
    pub frequencies_hz: Vec<f64>,
    /// Mode shapes per node (φᵀ M φ = 1; zero at fixed DOFs; largest component positive).
    pub shapes: Vec<Vec<Vector3<f64>>>,
    /// Final convergence measures: the sine of the M-angle between A φ and the basis
    /// (A = (K − σM)⁻¹M), ≈ ‖Aφ − θφ‖ / (θ‖φ‖) with θ = 1/(λ − σ).
    pub residuals: Vec<f64>,
    /// The shift σ used, in (rad/s)².
    pub shift: f64,
    /// Block steps taken.
    pub iterations: usize,
    /// Right-hand sides solved with the shifted factor.
    pub solves: usize,
    /// Wall time per phase (this system's assembly and ordering included, on first use).
    pub timings: PhaseTimes,
}

/// Fraction of mean(diag K / diag M) used as the negative automatic shift.
const AUTO_SHIFT_FRACTION: f64 = 1e-8;

impl FemSystem<'_> {
    /// The lowest `k` modes of this system.
    pub fn modes(&mut self, k: usize, options: &ModeOptions) -> Result<Modes> {
        let n = self.dofs.free_count();
        if k == 0 || k > n {
            return Err(Error::Message(format!(
                "fem: {k} modes asked for a system of {n} free DOFs"
            )));
        }
        if !(options.tol > 0.0 && options.tol.is_finite()) || options.max_iter == 0 {
            return Err(Error::Message(format!(
                "fem: mode options need tol > 0 and max_iter > 0 (got tol {}, max_iter {})",
                options.tol, options.max_iter
            )));
        }
        let mut times = self.setup_times;
        self.setup_times = PhaseTimes::default();
        let start = Instant::now();
        let mass = self
            .model
            .assemble_mass(&self.pattern, &self.dofs, options.mass);
        times.assembly_s += seconds_since(start);

        let negative_shift = {
            let dk = self.pattern.diagonal(&self.stiffness);
            let dm = self.pattern.diagonal(&mass);
            let mean = dk.iter().zip(&dm).map(|(k, m)| k / m).sum::<f64>() / n as f64;
            -AUTO_SHIFT_FRACTION * mean
        };
        let mut shift = match options.shift {
            Shift::Value(s) => s,
            Shift::Auto if self.anchored => 0.0,
            Shift::Auto => negative_shift,
        };
        if !shift.is_finite() {
            return Err(Error::Message(format!(
                "fem: the shift {shift} is not finite"
            )));
        }
        let shifted: Option<Factor> = if shift == 0.0 {
            match self.stiffness_factor(&mut times) {
                Ok(_) => None,
                Err(e) if options.shift != Shift::Auto => return Err(e),
                Err(_) => {
                    // Anchored on paper but singular (a mechanism): use a negative shift.
                    shift = negative_shift;
                    Some(self.shifted_factor(&mass, shift, &mut times)?)
                }
            }
        } else {
            Some(self.shifted_factor(&mass, shift, &mut times)?)
        };
        let factor = match &shifted {
            Some(f) => f,
            None => self.stiffness_factor.as_ref().expect("factorised above"),
        };

        let start = Instant::now();
        let problem = Problem {
            system: self,
            mass: &mass,
            factor,
            shift,
        };
        let outcome = problem.lanczos(k, options)?;
        times.eigen_s += seconds_since(start);
        let shapes = outcome
            .vectors
            .iter()
            .map(|v| self.dofs.expand_homogeneous(v))
            .collect();
        Ok(Modes {
            frequencies_hz: outcome
                .values
                .iter()
                .map(|&l| l.signum() * l.abs().sqrt() / (2.0 * std::f64::consts::PI))
                .collect(),
            eigenvalues: outcome.values,
            shapes,
            residuals: outcome.residuals,
            shift,
            iterations: outcome.iterations,
            solves: outcome.solves,
            timings: times,
        })
    }

    fn shifted_factor(&self, mass: &[f64], shift: f64, times: &mut PhaseTimes) -> Result<Factor> {
        let start = Instant::now();
        let values: Vec<f64> = self
            .stiffness
            .iter()
            .zip(mass)
            .map(|(k, m)| k - shift * m)
            .collect();
        let factor = Factor::new(&self.symbolic, &self.pattern, &values)?;
        times.factorisation_s += seconds_since(start);
        factor.ok_or_else(|| {
            Error::Message(format!(
                "fem: K − σM is not positive definite for the shift σ = {shift:e} (rad/s)²: \
                 the shift must lie below the lowest eigenvalue"
            ))
        })
    }
}

struct Problem<'a, 's> {
    system: &'a FemSystem<'s>,
    mass: &'a [f64],
    factor: &'a Factor,
    shift: f64,
}

struct Outcome {
    values: Vec<f64>,
    vectors: Vec<Vec<f64>>,
    residuals: Vec<f64>,
    iterations: usize,
    solves: usize,
}

/// An M-orthonormal basis V with M V and A V (A V known for the first `solved` columns)
/// and the projection H = (M V)ᵀ A V of the solved part.
struct Basis {
    v: Mat<f64>,
    mv: Mat<f64>,
    av: Mat<f64>,
    h: DMatrix<f64>,
    len: usize,
    solved: usize,
}

fn par() -> Par {
    faer::get_global_parallelism()
}

impl Problem<'_, '_> {
    fn mul_m(&self, x: MatRef<'_, f64>) -> Mat<f64> {
        let mut y = Mat::<f64>::zeros(x.nrows(), x.ncols());
        let mut column = vec![0.0; x.nrows()];
        for j in 0..x.ncols() {
            for (i, c) in column.iter_mut().enumerate() {
                *c = x[(i, j)];
            }
            self.system
                .pattern
                .mul_vec(self.mass, &column, y.col_as_slice_mut(j));
        }
        y
    }

    /// Appends the M-orthonormalised part of `w` that is new to the basis (dropping
    /// directions within 1e-10 of it); returns the number of vectors added.
    fn extend(&self, basis: &mut Basis, mut w: Mat<f64>) -> usize {
        let room = basis.v.ncols() - basis.len;
        let mut mw = self.mul_m(w.as_ref());
        let scale = (0..w.ncols())
            .map(|j| dot(w.as_ref(), j, mw.as_ref(), j))
            .fold(0.0, f64::max);
        if !(scale > 0.0 && scale.is_finite()) {
            return 0;
        }
        for pass in 0..2 {
            if basis.len > 0 {
                let v = basis.v.as_ref().subcols(0, basis.len);
                let mv = basis.mv.as_ref().subcols(0, basis.len);
                for _ in 0..2 - pass {
                    let mut c = Mat::<f64>::zeros(basis.len, w.ncols());
                    matmul(
                        c.as_mut(),
                        Accum::Replace,
                        mv.transpose(),
                        w.as_ref(),
                        1.0,
                        par(),
                    );
                    matmul(w.as_mut(), Accum::Add, v, c.as_ref(), -1.0, par());
                    matmul(mw.as_mut(), Accum::Add, mv, c.as_ref(), -1.0, par());
                }
            }
            // Orthonormalise within the block by the eigenvectors of its Gram matrix.
            let cols = w.ncols();
            let gram = DMatrix::<f64>::from_fn(cols, cols, |i, j| {
                0.5 * (dot(w.as_ref(), i, mw.as_ref(), j) + dot(w.as_ref(), j, mw.as_ref(), i))
            });
            let eig = SymmetricEigen::new(gram);
            // First pass: what is left of a direction within 1e-10 of the basis is noise;
            // second pass (normalised vectors): what re-projection still shrinks a lot.
            let threshold = if pass == 0 { 1e-20 * scale } else { 1e-2 };
            let mut keep: Vec<usize> = (0..cols)
                .filter(|&i| eig.eigenvalues[i] > threshold)
                .collect();
            keep.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
            keep.truncate(room);
            if keep.is_empty() {
                return 0;
            }
            let t = Mat::<f64>::from_fn(cols, keep.len(), |r, c| {
                eig.eigenvectors[(r, keep[c])] / eig.eigenvalues[keep[c]].sqrt()
            });
            w = w.as_ref() * t.as_ref();
            mw = if pass == 0 {
                // Recomputed, not updated: the normalisation amplifies rounding in M w.
                self.mul_m(w.as_ref())
            } else {
                // t is well conditioned here (its eigenvalues are ≥ 1e-2).
                mw.as_ref() * t.as_ref()
            };
        }
        let added = w.ncols();
        let start = basis.len;
        basis
            .v
            .as_mut()
            .subcols_mut(start, added)
            .copy_from(w.as_ref());
        basis
            .mv
            .as_mut()
            .subcols_mut(start, added)
            .copy_from(mw.as_ref());
        basis.len += added;
        added
    }

    /// Applies A = (K − σM)⁻¹ M to the basis vectors not solved yet and extends H.
    fn solve_pending(&self, basis: &mut Basis, solves: &mut usize) {
        let (old, m) = (basis.solved, basis.len);
        if old == m {
            return;
        }
        let mut w = basis.mv.as_ref().subcols(old, m - old).to_owned();
        *solves += w.ncols();
        self.factor.solve_in_place(w.as_mut());
        basis
            .av
            .as_mut()
            .subcols_mut(old, m - old)
            .copy_from(w.as_ref());
        let mv = basis.mv.as_ref().subcols(0, m);
        let av = basis.av.as_ref().subcols(0, m);
        // New columns (M V)ᵀ A V_new and new rows (M V_new)ᵀ A V, averaged: H is
        // symmetric in exact arithmetic.
        let cols = mv.transpose() * w.as_ref();
        let rows = basis.mv.as_ref().subcols(old, m - old).transpose() * av;
        let mut h = DMatrix::<f64>::zeros(m, m);
        h.view_mut((0, 0), (old, old)).copy_from(&basis.h);
        for c in old..m {
            for r in 0..m {
                let value = 0.5 * (cols[(r, c - old)] + rows[(c - old, r)]);
                h[(r, c)] = value;
                h[(c, r)] = value;
            }
        }
        basis.h = h;
        basis.solved = m;
    }

    fn lanczos(&self, k: usize, options: &ModeOptions) -> Result<Outcome> {
        let n = self.system.dofs.free_count();
        let block = options.block_size.unwrap_or(k.max(6)).max(k).min(n);
        let cap = options
            .max_basis
            .unwrap_or((2 * k + 4 * block).max(24))
            .max(k + 2 * block)
            .min(n);
        let mut basis = Basis {
            v: Mat::zeros(n, cap),
            mv: Mat::zeros(n, cap),
            av: Mat::zeros(n, cap),
            h: DMatrix::zeros(0, 0),
            len: 0,
            solved: 0,
        };
        let mut rng = crate::geometry::random::SplitMix(options.seed);
        let mut solves = 0;
        let mut random = |cols: usize| Mat::<f64>::from_fn(n, cols, |_, _| rng.next_signed());
        self.extend(&mut basis, random(block));
        let mut last_residuals = Vec::new();
        for iteration in 1..=options.max_iter {
            self.solve_pending(&mut basis, &mut solves);
            // Rayleigh–Ritz with A: the largest θ give the lowest λ = σ + 1/θ.
            let m = basis.len;
            let eig = SymmetricEigen::new(basis.h.clone());
            let mut order: Vec<usize> = (0..m).collect();
            order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
            let theta: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
            let s = Mat::<f64>::from_fn(m, m, |r, c| eig.eigenvectors[(r, order[c])]);
            // Residuals of the lowest `width` pairs, taken orthogonal to the basis:
            // (I − V (MV)ᵀ) A V s. Solve errors along basis vectors do not count.
            let width = block.min(m);
            let wanted = k.min(width);
            let v = basis.v.as_ref().subcols(0, m);
            let mv = basis.mv.as_ref().subcols(0, m);
            let av = basis.av.as_ref().subcols(0, m);
            let s_width = s.as_ref().subcols(0, width);
            let phi = v * s.as_ref().subcols(0, wanted);
            let mut r = av * s_width;
            for _ in 0..2 {
                let c = mv.transpose() * r.as_ref();
                matmul(r.as_mut(), Accum::Add, v, c.as_ref(), -1.0, par());
            }
            let residuals: Vec<f64> = (0..width)
                .map(|j| {
                    let norm_r = dot(r.as_ref(), j, r.as_ref(), j).sqrt();
                    let norm_phi: f64 = {
                        let p = v * s.as_ref().subcols(j, 1);
                        dot(p.as_ref(), 0, p.as_ref(), 0).sqrt()
                    };
                    norm_r / (theta[j].abs() * norm_phi).max(f64::MIN_POSITIVE)
                })
                .collect();
            let converged = |j: usize| residuals[j] <= options.tol;
            if (wanted == k && (0..k).all(converged)) || m == n {
                let values: Vec<f64> = theta[..k].iter().map(|t| self.shift + 1.0 / t).collect();
                return Ok(Outcome {
                    values,
                    vectors: (0..k)
                        .map(|j| normalise_sign(phi.col_as_slice(j)))
                        .collect(),
                    residuals: residuals[..k].to_vec(),
                    iterations: iteration,
                    solves,
                });
            }
            last_residuals = residuals[..wanted].to_vec();
            // Next block: residuals of the unconverged lowest pairs (block Krylov step).
            let expand: Vec<usize> = (0..width).filter(|&j| !converged(j)).collect();
            let next = Mat::<f64>::from_fn(n, expand.len(), |i, c| r[(i, expand[c])]);
            if m + expand.len() > cap {
                // Thick restart: keep the lowest Ritz vectors (their A V and H follow).
                let keep = (k + block).min(m).min(cap - expand.len());
                let s_keep = s.as_ref().subcols(0, keep);
                let new_v = v * s_keep;
                let new_mv = mv * s_keep;
                let new_av = av * s_keep;
                basis
                    .v
                    .as_mut()
                    .subcols_mut(0, keep)
                    .copy_from(new_v.as_ref());
                basis
                    .mv
                    .as_mut()
                    .subcols_mut(0, keep)
                    .copy_from(new_mv.as_ref());
                basis
                    .av
                    .as_mut()
                    .subcols_mut(0, keep)
                    .copy_from(new_av.as_ref());
                basis.h =
                    DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&theta[..keep]));
                basis.len = keep;
                basis.solved = keep;
            }
            if self.extend(&mut basis, next) == 0 {
                // Nothing new (an invariant subspace short of the wanted pairs).
                let room = (cap - basis.len).min(block);
                if room == 0 || self.extend(&mut basis, random(room)) == 0 {
                    break;
                }
            }
        }
        Err(Error::Message(format!(
            "fem: the eigensolver did not converge in {} block steps (residuals {:?}, tol {:e}); \
             raise max_iter or move the shift closer to the lowest eigenvalue",
            options.max_iter, last_residuals, options.tol
        )))
    }
}

fn dot(a: MatRef<'_, f64>, i: usize, b: MatRef<'_, f64>, j: usize) -> f64 {
    (0..a.nrows()).map(|r| a[(r, i)] * b[(r, j)]).sum()
}

/// A copy of `v` with its largest-magnitude component made positive (a fixed sign).
fn normalise_sign(v: &[f64]) -> Vec<f64> {
    let largest = v
        .iter()
        .copied()
        .fold(0.0f64, |acc, x| if x.abs() > acc.abs() { x } else { acc });
    let sign = if largest < 0.0 { -1.0 } else { 1.0 };
    v.iter().map(|x| sign * x).collect()
}
