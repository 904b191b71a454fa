//! The exact local 3-D Coulomb solver (one contact, W_aa and q_a given) and the cone
//! algebra shared by the NLGS and the error measure.
//!
//! The local problem is `u = W r + q`, `r ∈ K`, `ũ = u + µ‖u_T‖ e_N ∈ K*`, `r ⊥ ũ`
//! (De Saxcé's modified velocity; `K = {‖r_T‖ ≤ µ r_N}`). It is solved by enumerating
//! Coulomb's three cases exactly:
//! 1. take-off, `q_N ≥ 0`: r = 0;
//! 2. stick, `r = −W⁻¹ q` inside the cone: u = 0;
//! 3. slip, r on the cone's surface, `u_N = 0`, `u_T = −λ d`, `r_T = µ r_N d`, `λ > 0`, ‖d‖ = 1.
//!    For a direction d, `u_N = 0` fixes `r_N = −q_N / (W_NN + µ W_NT·d)`; what remains is
//!    one scalar equation in the angle of d, `f(θ) = d⊥ · u_T · (W_NN + µ W_NT·d) = 0`,
//!    a trigonometric polynomial of degree 2 (at most four roots). Newton's method on θ from
//!    the previous sweep's direction (or from the stick solution's direction) finds it in
//!    2–4 steps; if that fails, every root is bracketed on a 96-angle grid and refined, and
//!    the root with `r_N > 0`, `λ ≥ 0` is kept.
//!
//! A last-resort projected fixed-point iteration covers a singular or indefinite W_aa;
//! the caller counts how often that happens.

use super::problem::Block3;

/// Which of Coulomb's cases a local solution is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ContactStatus {
    /// `q_N ≥ 0`: no impulse.
    TakeOff,
    /// The impulse is inside the cone and the relative velocity is zero.
    Stick,
    /// The impulse is on the cone's surface, opposite to the tangential velocity.
    Slip,
    /// No exact case matched (singular or indefinite W_aa): the projected fixed-point
    /// fallback's answer.
    Fallback,
}

/// Projects `r` on the friction cone `K = {‖r_T‖ ≤ µ r_N}` (Euclidean projection).
#[inline]
pub fn project_on_cone(r: [f64; 3], mu: f64) -> [f64; 3] {
    let norm_t = norm2(r[1], r[2]);
    if mu * norm_t <= -r[0] {
        [0.0; 3]
    } else if norm_t <= mu * r[0] {
        r
    } else {
        let normal = (mu * norm_t + r[0]) / (mu * mu + 1.0);
        let scale = mu * normal / norm_t;
        [normal, scale * r[1], scale * r[2]]
    }
}

/// `‖e_a‖²` of the Siconos error measure at one contact: `e_a = r − Π_K(r − ũ)` with
/// `ũ = [u_N + µ‖u_T‖, u_T]`.
#[inline]
pub fn coulomb_residual_squared(r: [f64; 3], u: [f64; 3], mu: f64) -> f64 {
    let shifted = [
        r[0] - u[0] - mu * norm2(u[1], u[2]),
        r[1] - u[1],
        r[2] - u[2],
    ];
    let p = project_on_cone(shifted, mu);
    (r[0] - p[0]).powi(2) + (r[1] - p[1]).powi(2) + (r[2] - p[2]).powi(2)
}

/// One contact's local solver: W_aa, its inverse when it has one, and µ.
#[derive(Debug, Clone)]
pub struct LocalCoulomb {
    w: Block3,
    w_inverse: Option<Block3>,
    mu: f64,
}

/// The slip equation's coefficients: `f(θ) = α_c c + α_s s + β_cc c² + β_ss s² + β_cs c s`.
#[derive(Debug, Clone, Copy)]
struct SlipEquation {
    alpha_c: f64,
    alpha_s: f64,
    beta_cc: f64,
    beta_ss: f64,
    beta_cs: f64,
}

impl SlipEquation {
    #[inline]
    fn value_and_slope(&self, d: [f64; 2]) -> (f64, f64) {
        let (c, s) = (d[0], d[1]);
        let value = self.alpha_c * c
            + self.alpha_s * s
            + self.beta_cc * c * c
            + self.beta_ss * s * s
            + self.beta_cs * c * s;
        let slope = -self.alpha_c * s
            + self.alpha_s * c
            + 2.0 * (self.beta_ss - self.beta_cc) * c * s
            + self.beta_cs * (c * c - s * s);
        (value, slope)
    }

    fn scale(&self) -> f64 {
        self.alpha_c.abs()
            + self.alpha_s.abs()
            + self.beta_cc.abs()
            + self.beta_ss.abs()
            + self.beta_cs.abs()
    }
}

/// Newton steps on the angle per local solve before the bracketing fallback.
const NEWTON_STEPS: usize = 30;
/// Angles of the bracketing grid.
const GRID: usize = 96;

impl LocalCoulomb {
    /// Prepares the local solver of a contact with diagonal block `w` and friction `mu`.
    pub fn new(w: &Block3, mu: f64) -> Self {
        Self::with_inverse(w, invert(w), mu)
    }

    /// [`Self::new`] with `w`'s inverse already computed by [`invert`].
    pub(crate) fn with_inverse(w: &Block3, w_inverse: Option<Block3>, mu: f64) -> Self {
        LocalCoulomb {
            w: *w,
            w_inverse,
            mu,
        }
    }

    /// Solves the local problem for the local free velocity `q` (q_a plus the other
    /// contacts' contributions). `direction` holds the last slip direction (unit, or zero
    /// if none) and is updated on slip.
    pub fn solve(&self, q: [f64; 3], direction: &mut [f64; 2]) -> ([f64; 3], ContactStatus) {
        let w = &self.w;
        let mu = self.mu;
        if q[0] >= 0.0 {
            return ([0.0; 3], ContactStatus::TakeOff);
        }
        if mu == 0.0 {
            if w[0] > 0.0 {
                return ([-q[0] / w[0], 0.0, 0.0], ContactStatus::Stick);
            }
            return (self.fallback(q), ContactStatus::Fallback);
        }
        let mut guess = *direction;
        if let Some(inv) = &self.w_inverse {
            let r = [
                -(inv[0] * q[0] + inv[1] * q[1] + inv[2] * q[2]),
                -(inv[3] * q[0] + inv[4] * q[1] + inv[5] * q[2]),
                -(inv[6] * q[0] + inv[7] * q[1] + inv[8] * q[2]),
            ];
            let cone = mu * r[0];
            if r[0] > 0.0 && r[1] * r[1] + r[2] * r[2] <= cone * cone {
                // Inside the cone (no square root: this is the most common case): what
                // `project_on_cone` would return.
                return (r, ContactStatus::Stick);
            }
            let norm_t = norm2(r[1], r[2]);
            if r[0] > 0.0 && norm_t <= mu * r[0] * (1.0 + 1e-13) {
                // Within rounding of the cone: stick (pulled exactly onto K if outside).
                return (project_on_cone(r, mu), ContactStatus::Stick);
            }
            if guess == [0.0, 0.0] && norm_t > 0.0 {
                guess = [r[1] / norm_t, r[2] / norm_t];
            }
        }
        let equation = self.slip_equation(q);
        if guess != [0.0, 0.0] {
            if let Some(d) = newton(&equation, guess) {
                if let Some(r) = self.slip_impulse(q, d) {
                    *direction = d;
                    return (r, ContactStatus::Slip);
                }
            }
        }
        if let Some((r, d)) = self.slip_by_brackets(q, &equation, guess) {
            *direction = d;
            return (r, ContactStatus::Slip);
        }
        (self.fallback(q), ContactStatus::Fallback)
    }

    fn slip_equation(&self, q: [f64; 3]) -> SlipEquation {
        let w = &self.w;
        let mu = self.mu;
        let (qn, q1, q2) = (q[0], q[1], q[2]);
        let (w00, b1, b2, a1, a2) = (w[0], w[1], w[2], w[3], w[6]);
        let (t11, t12, t21, t22) = (w[4], w[5], w[7], w[8]);
        SlipEquation {
            alpha_c: -qn * a2 + w00 * q2,
            alpha_s: qn * a1 - w00 * q1,
            beta_cc: mu * (-qn * t21 + b1 * q2),
            beta_ss: mu * (qn * t12 - b2 * q1),
            beta_cs: mu * (-qn * (t22 - t11) + b2 * q2 - b1 * q1),
        }
    }

    /// The slip impulse for direction `d` if it is admissible: `r_N > 0` and the
    /// tangential velocity opposite to d (λ ≥ 0 up to rounding).
    fn slip_impulse(&self, q: [f64; 3], d: [f64; 2]) -> Option<[f64; 3]> {
        let w = &self.w;
        let mu = self.mu;
        let denominator = w[0] + mu * (w[1] * d[0] + w[2] * d[1]);
        if denominator <= 0.0 {
            return None;
        }
        let normal = -q[0] / denominator;
        let r = [normal, mu * normal * d[0], mu * normal * d[1]];
        let u1 = w[3] * r[0] + w[4] * r[1] + w[5] * r[2] + q[1];
        let u2 = w[6] * r[0] + w[7] * r[1] + w[8] * r[2] + q[2];
        let lambda = -(u1 * d[0] + u2 * d[1]);
        let scale = q[1].abs() + q[2].abs() + q[0].abs() * (1.0 + mu);
        (lambda >= -1e-12 * scale).then_some(r)
    }

    /// Brackets every root of the slip equation on a grid, refines each, and returns an
    /// admissible one (the closest to `guess` when several are).
    fn slip_by_brackets(
        &self,
        q: [f64; 3],
        equation: &SlipEquation,
        guess: [f64; 2],
    ) -> Option<([f64; 3], [f64; 2])> {
        let step = std::f64::consts::TAU / GRID as f64;
        let at = |k: usize| {
            let (s, c) = (k as f64 * step).sin_cos();
            [c, s]
        };
        let values: Vec<f64> = (0..GRID)
            .map(|k| equation.value_and_slope(at(k)).0)
            .collect();
        let mut best: Option<([f64; 3], [f64; 2], f64)> = None;
        let tiny = 1e-11 * equation.scale();
        let mut consider = |d: [f64; 2]| {
            if equation.value_and_slope(d).0.abs() > tiny {
                return;
            }
            if let Some(r) = self.slip_impulse(q, d) {
                let distance = (d[0] - guess[0]).powi(2) + (d[1] - guess[1]).powi(2);
                if best.is_none_or(|b| distance < b.2) {
                    best = Some((r, d, distance));
                }
            }
        };
        for k in 0..GRID {
            let (f0, f1) = (values[k], values[(k + 1) % GRID]);
            let previous = values[(k + GRID - 1) % GRID];
            if f0 == 0.0 {
                consider(at(k));
            } else if f0 * f1 < 0.0 {
                let lo = k as f64 * step;
                consider(bisect_newton(equation, lo, lo + step, f0));
            } else if f0.abs() < previous.abs() && f0.abs() < f1.abs() {
                // A local minimum of |f| without a sign change: a near-double root.
                if let Some(d) = newton(equation, at(k)) {
                    consider(d);
                }
            }
        }
        best.map(|(r, d, _)| (r, d))
    }

    /// Projected fixed point `r ← Π_K(r − ρ ũ(r))`, for singular or indefinite blocks.
    fn fallback(&self, q: [f64; 3]) -> [f64; 3] {
        let w = &self.w;
        let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm == 0.0 {
            return [0.0; 3];
        }
        let rho = 1.0 / norm;
        let mut r = [0.0; 3];
        for _ in 0..1000 {
            let u = apply(w, r, q);
            let shifted = [
                r[0] - rho * (u[0] + self.mu * norm2(u[1], u[2])),
                r[1] - rho * u[1],
                r[2] - rho * u[2],
            ];
            let next = project_on_cone(shifted, self.mu);
            let change = (next[0] - r[0]).abs() + (next[1] - r[1]).abs() + (next[2] - r[2]).abs();
            r = next;
            if change <= 1e-15 * (r[0].abs() + r[1].abs() + r[2].abs()) {
                break;
            }
        }
        r
    }
}

/// `√(x² + y²)`: libm's `hypot` guards against overflow and underflow that impulses and
/// velocities never reach, at several times the cost of a square root (it was a third of
/// the NLGS time).
#[inline(always)]
pub fn norm2(x: f64, y: f64) -> f64 {
    (x * x + y * y).sqrt()
}

/// `W r + q` for one block.
#[inline]
pub(crate) fn apply(w: &Block3, r: [f64; 3], q: [f64; 3]) -> [f64; 3] {
    let mut u = q;
    super::problem::mul_add(w, &r, &mut u);
    u
}

/// Newton's method on the angle of d, steps limited to 0.5 rad; `None` if it does not
/// converge.
fn newton(equation: &SlipEquation, start: [f64; 2]) -> Option<[f64; 2]> {
    let mut d = start;
    let tiny = 1e-14 * equation.scale();
    for _ in 0..NEWTON_STEPS {
        let (value, slope) = equation.value_and_slope(d);
        if value.abs() <= tiny {
            return Some(d);
        }
        if slope == 0.0 {
            return None;
        }
        let step = (-value / slope).clamp(-0.5, 0.5);
        d = rotate(d, step);
        if step.abs() <= 1e-15 {
            return Some(d);
        }
    }
    None
}

/// Rotates the unit vector d by `atan(step)` (≈ step for the small steps of Newton).
#[inline]
fn rotate(d: [f64; 2], step: f64) -> [f64; 2] {
    let (c, s) = (d[0] - step * d[1], d[1] + step * d[0]);
    let inverse = 1.0 / norm2(c, s);
    [c * inverse, s * inverse]
}

/// A root of f in [lo, hi] where f(lo) = `f_lo` and f(hi) have opposite signs: Newton
/// steps kept inside the bracket, bisection otherwise.
fn bisect_newton(equation: &SlipEquation, mut lo: f64, mut hi: f64, f_lo: f64) -> [f64; 2] {
    let direction = |theta: f64| {
        let (s, c) = theta.sin_cos();
        [c, s]
    };
    let mut theta = 0.5 * (lo + hi);
    for _ in 0..100 {
        let (value, slope) = equation.value_and_slope(direction(theta));
        if value == 0.0 {
            break;
        }
        if (value < 0.0) == (f_lo < 0.0) {
            lo = theta;
        } else {
            hi = theta;
        }
        let newton = theta - value / slope;
        if slope != 0.0 && (value / slope).abs() <= 1e-15 {
            // Converged: the step is below rounding (and may not move theta at all).
            theta = newton;
            break;
        }
        theta = if slope != 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if hi - lo <= 1e-15 {
            break;
        }
    }
    direction(theta)
}

/// The inverse of a 3 × 3 block, `None` when it is singular to rounding.
pub(crate) fn invert(w: &Block3) -> Option<Block3> {
    let cofactor = [
        w[4] * w[8] - w[5] * w[7],
        w[5] * w[6] - w[3] * w[8],
        w[3] * w[7] - w[4] * w[6],
    ];
    let det = w[0] * cofactor[0] + w[1] * cofactor[1] + w[2] * cofactor[2];
    let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
    // Written so that a NaN determinant also counts as singular.
    if det.is_nan() || det.abs() <= 1e-13 * norm * norm * norm {
        return None;
    }
    let inv_det = 1.0 / det;
    Some([
        cofactor[0] * inv_det,
        (w[2] * w[7] - w[1] * w[8]) * inv_det,
        (w[1] * w[5] - w[2] * w[4]) * inv_det,
        cofactor[1] * inv_det,
        (w[0] * w[8] - w[2] * w[6]) * inv_det,
        (w[2] * w[3] - w[0] * w[5]) * inv_det,
        cofactor[2] * inv_det,
        (w[1] * w[6] - w[0] * w[7]) * inv_det,
        (w[0] * w[4] - w[1] * w[3]) * inv_det,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    const IDENTITY: Block3 = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

    fn residual(w: &Block3, q: [f64; 3], mu: f64, r: [f64; 3]) -> f64 {
        coulomb_residual_squared(r, apply(w, r, q), mu).sqrt()
    }

    #[test]
    fn inverse_is_an_inverse() {
        let w = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let inv = invert(&w).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| w[3 * i + k] * inv[3 * k + j]).sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-14);
            }
        }
        assert!(invert(&[1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 0.0, 1.0]).is_none());
    }

    #[test]
    fn projection_cases() {
        assert_eq!(project_on_cone([1.0, 0.1, 0.0], 0.5), [1.0, 0.1, 0.0]);
        assert_eq!(project_on_cone([-1.0, 0.1, 0.0], 0.5), [0.0; 3]);
        let p = project_on_cone([0.0, 1.0, 0.0], 1.0);
        assert!((p[0] - 0.5).abs() < 1e-15 && (p[1] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn take_off() {
        let local = LocalCoulomb::new(&IDENTITY, 0.3);
        let (r, status) = local.solve([0.5, 1.0, -2.0], &mut [0.0; 2]);
        assert_eq!((r, status), ([0.0; 3], ContactStatus::TakeOff));
    }

    #[test]
    fn stick_identity() {
        let local = LocalCoulomb::new(&IDENTITY, 0.5);
        let (r, status) = local.solve([-1.0, 0.2, -0.1], &mut [0.0; 2]);
        assert_eq!(status, ContactStatus::Stick);
        assert_eq!(r, [1.0, -0.2, 0.1]);
    }

    #[test]
    fn slip_identity_analytic() {
        // W = I: r_N = −q_N, r_T = −µ r_N q_T/‖q_T‖, u_T = q_T (1 − µ r_N/‖q_T‖).
        let (mu, q) = (0.3, [-1.0, 3.0, 4.0]);
        let local = LocalCoulomb::new(&IDENTITY, mu);
        let mut direction = [0.0; 2];
        let (r, status) = local.solve(q, &mut direction);
        assert_eq!(status, ContactStatus::Slip);
        let expect = [1.0, -0.3 * 0.6, -0.3 * 0.8];
        for i in 0..3 {
            assert!((r[i] - expect[i]).abs() < 1e-14, "{r:?}");
        }
        assert!(residual(&IDENTITY, q, mu, r) < 1e-12);
        assert!((direction[0] + 0.6).abs() < 1e-14 && (direction[1] + 0.8).abs() < 1e-14);
    }

    #[test]
    fn slip_with_coupled_block_satisfies_coulomb() {
        let w = [2.0, 0.3, -0.2, 0.3, 1.5, 0.1, -0.2, 0.1, 1.2];
        for (k, mu) in [0.1, 0.3, 0.7, 1.0, 2.0].into_iter().enumerate() {
            for j in 0..40 {
                let angle = j as f64 * 0.37 + k as f64;
                let q = [-1.0 - 0.1 * j as f64, 3.0 * angle.cos(), 2.0 * angle.sin()];
                for warm in [[0.0, 0.0], [1.0, 0.0], [0.0, -1.0]] {
                    let mut direction = warm;
                    let (r, status) = LocalCoulomb::new(&w, mu).solve(q, &mut direction);
                    assert_ne!(status, ContactStatus::Fallback);
                    let scale = q.iter().map(|x| x.abs()).sum::<f64>();
                    assert!(residual(&w, q, mu, r) < 1e-12 * scale, "µ {mu} q {q:?}");
                }
            }
        }
    }

    #[test]
    fn frictionless_and_singular() {
        let local = LocalCoulomb::new(&IDENTITY, 0.0);
        assert_eq!(
            local.solve([-2.0, 1.0, 1.0], &mut [0.0; 2]).0,
            [2.0, 0.0, 0.0]
        );
        // A rank-one block (normal direction only): no inverse, still solved.
        let w = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let (r, _) = LocalCoulomb::new(&w, 0.5).solve([-1.0, 0.0, 0.0], &mut [0.0; 2]);
        assert!(residual(&w, [-1.0, 0.0, 0.0], 0.5, r) < 1e-12);
    }
}
