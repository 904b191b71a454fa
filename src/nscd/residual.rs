//! The Siconos error measure (Siconos 4.4 `fc3d_compute_error`).
//!
//! For each contact `e_a = r_a − Π_K(r_a − [u_aN + µ_a ‖u_aT‖, u_aT])`; the error is
//! `√(Σ_a ‖e_a‖²) / max(‖q‖, ‖r‖, ‖u‖)` (not divided when that maximum is below machine
//! epsilon). It is zero exactly at a solution.

use super::coulomb::coulomb_residual_squared;
use super::problem::FrictionProblem;

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// The Siconos error of the impulse `r`, given `u = W r + q` already computed.
pub fn siconos_error_with_velocity(problem: &FrictionProblem, r: &[f64], u: &[f64]) -> f64 {
    let mut sum = 0.0;
    for (a, &mu) in problem.friction.iter().enumerate() {
        let ra = [r[3 * a], r[3 * a + 1], r[3 * a + 2]];
        let ua = [u[3 * a], u[3 * a + 1], u[3 * a + 2]];
        sum += coulomb_residual_squared(ra, ua, mu);
    }
    let scale = norm(&problem.free_velocity).max(norm(r)).max(norm(u));
    if scale > f64::EPSILON {
        sum.sqrt() / scale
    } else {
        sum.sqrt()
    }
}

/// The Siconos error of the impulse `r`; writes `u = W r + q` into `u`.
pub fn siconos_error(problem: &FrictionProblem, r: &[f64], u: &mut [f64]) -> f64 {
    problem.delassus.affine(r, &problem.free_velocity, u);
    siconos_error_with_velocity(problem, r, u)
}
