//! Non-linear Gauss–Seidel (NSGS) over contacts, W form (seed 000 §2.1.3).
//!
//! Sweep k + 1 visits the contacts in order; for contact a it forms the local free
//! velocity `q_a + Σ_{b≠a} W_ab r_b` from the off-diagonal blocks of block row a (the
//! newest r_b, already updated for b < a), solves the local Coulomb problem exactly
//! ([`LocalCoulomb`]) and overwrites r_a in place. A sweep reads W once: O(blocks).

use std::time::{Duration, Instant};

use super::coulomb::{ContactStatus, LocalCoulomb};
use super::problem::{mul_add, FrictionProblem};
use super::residual::siconos_error;

/// When NLGS stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stopping {
    /// Until the Siconos error measure ([`super::residual`]) is at most `tolerance`, or
    /// after `max_sweeps` sweeps.
    Tolerance {
        /// The target error.
        tolerance: f64,
        /// The cap on sweeps.
        max_sweeps: usize,
    },
    /// Exactly this many sweeps (the seed's n_DDM); the error is measured once at the end.
    Sweeps(usize),
}

/// How often the (full) error measure is computed under [`Stopping::Tolerance`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCheck {
    /// After every sweep (one product `W r + q` per sweep: twice a sweep's cost).
    EverySweep,
    /// The change `‖r^{k+1} − r^k‖ / ‖r^{k+1}‖` is summed during the sweep for free; the
    /// full measure is computed when that falls below the tolerance, and every
    /// `every` sweeps anyway. Stops only on the full measure.
    Light {
        /// Full measure at least every this many sweeps.
        every: usize,
    },
}

impl ErrorCheck {
    /// Whether the full error measure is due after sweep `iterations`, given the
    /// sweep's summed squared impulse change and squared impulse size. Never under a
    /// fixed sweep count (`tolerance` = −∞). Shared by the W-form and the body-velocity
    /// sweeps.
    pub fn due(self, iterations: usize, change: f64, size: f64, tolerance: f64) -> bool {
        match self {
            _ if tolerance == f64::NEG_INFINITY => false,
            ErrorCheck::EverySweep => true,
            ErrorCheck::Light { every } => {
                let light = if size > 0.0 {
                    (change / size).sqrt()
                } else {
                    change.sqrt()
                };
                light <= tolerance || iterations % every.max(1) == 0
            }
        }
    }
}

/// NLGS options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NlgsOptions {
    /// When to stop.
    pub stopping: Stopping,
    /// How often the error is measured.
    pub error_check: ErrorCheck,
}

impl Default for NlgsOptions {
    fn default() -> Self {
        NlgsOptions {
            stopping: Stopping::Tolerance {
                tolerance: 1e-8,
                max_sweeps: 10_000,
            },
            error_check: ErrorCheck::Light { every: 20 },
        }
    }
}

/// What an NLGS run did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NlgsReport {
    /// Sweeps made.
    pub iterations: usize,
    /// The Siconos error measure of the final impulse.
    pub error: f64,
    /// Whether the tolerance was met (always true for [`Stopping::Sweeps`]).
    pub converged: bool,
    /// Wall time of the solve (set-up of the local solvers included).
    pub solve_time: Duration,
    /// Times the full error measure was computed.
    pub error_evaluations: usize,
    /// Local solves that fell back to the projected fixed point (singular W_aa).
    pub local_fallbacks: usize,
    /// The sweep whose impulse is returned: `iterations`, except when the cap was hit
    /// and an earlier measured iterate had a lower error (see [`solve`]).
    pub returned_sweep: usize,
}

/// Solves `problem` by NLGS from the impulse in `impulse` (zero for a cold start, the
/// previous step's for a warm one). On return `impulse` holds r and `velocity` holds
/// `u = W r + q`.
///
/// Under [`Stopping::Tolerance`], when the cap is reached without convergence, the
/// measured iterate with the lowest error is returned (NSGS on a hard problem often
/// settles in a cycle whose error varies several-fold from sweep to sweep); under
/// [`Stopping::Sweeps`] the last iterate is.
pub fn solve(
    problem: &FrictionProblem,
    impulse: &mut [f64],
    velocity: &mut [f64],
    options: &NlgsOptions,
) -> NlgsReport {
    let start = Instant::now();
    let nc = problem.contact_count();
    assert_eq!(
        impulse.len(),
        3 * nc,
        "impulse must have 3 values per contact"
    );
    assert_eq!(
        velocity.len(),
        3 * nc,
        "velocity must have 3 values per contact"
    );
    let w = &problem.delassus;
    let locals: Vec<LocalCoulomb> = (0..nc)
        .map(|a| LocalCoulomb::new(w.diagonal(a), problem.friction[a]))
        .collect();
    let mut directions = vec![[0.0f64; 2]; nc];
    let q = &problem.free_velocity;
    let mut report = NlgsReport {
        iterations: 0,
        error: f64::INFINITY,
        converged: false,
        solve_time: Duration::ZERO,
        error_evaluations: 0,
        local_fallbacks: 0,
        returned_sweep: 0,
    };
    let mut best_error = f64::INFINITY;
    let mut best_sweep = 0;
    let mut best_impulse = Vec::new();
    let (tolerance, max_sweeps) = match options.stopping {
        Stopping::Tolerance {
            tolerance,
            max_sweeps,
        } => (tolerance, max_sweeps),
        Stopping::Sweeps(n) => (f64::NEG_INFINITY, n),
    };
    while report.iterations < max_sweeps {
        let mut change = 0.0;
        let mut size = 0.0;
        for a in 0..nc {
            let mut local_q = [q[3 * a], q[3 * a + 1], q[3 * a + 2]];
            let (columns, blocks) = w.row(a);
            for (&b, block) in columns.iter().zip(blocks) {
                let b = 3 * b as usize;
                mul_add(block, &impulse[b..b + 3], &mut local_q);
            }
            let (r, status) = locals[a].solve(local_q, &mut directions[a]);
            if status == ContactStatus::Fallback {
                report.local_fallbacks += 1;
            }
            let old = &mut impulse[3 * a..3 * a + 3];
            change += (r[0] - old[0]).powi(2) + (r[1] - old[1]).powi(2) + (r[2] - old[2]).powi(2);
            size += r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            old.copy_from_slice(&r);
        }
        report.iterations += 1;
        let measure = options
            .error_check
            .due(report.iterations, change, size, tolerance);
        if measure {
            report.error = siconos_error(problem, impulse, velocity);
            report.error_evaluations += 1;
            if report.error <= tolerance {
                report.converged = true;
                break;
            }
            if report.error < best_error {
                best_error = report.error;
                best_sweep = report.iterations;
                best_impulse.clear();
                best_impulse.extend_from_slice(impulse);
            }
        }
    }
    report.returned_sweep = report.iterations;
    if !report.converged {
        report.error = siconos_error(problem, impulse, velocity);
        report.error_evaluations += 1;
        report.converged = report.error <= tolerance;
        if best_error < report.error {
            impulse.copy_from_slice(&best_impulse);
            report.error = siconos_error(problem, impulse, velocity);
            report.error_evaluations += 1;
            report.returned_sweep = best_sweep;
        }
    }
    report.solve_time = start.elapsed();
    report
}
