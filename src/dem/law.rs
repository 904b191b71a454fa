//! The contact law between two vertex spheres (seed 004 §4): a linear normal spring, a
//! tangential spring with a Coulomb slider, and (only where a rigid body takes part) a
//! normal dashpot standing in for the material viscosity a rigid body does not have.

use serde::{Deserialize, Serialize};

/// The contact properties of one material's spheres (seed 004 Table 1).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SphereMaterial {
    /// Normal spring constant k_n (N/m): ballast 1.613 GN/m, sleeper 2.390 GN/m.
    pub normal_stiffness: f64,
    /// Tangential spring constant k_t (N/m): ballast 0.672 GN/m, sleeper 1.024 GN/m
    /// (Table 1's values are k_n / (2(1 + ν)), the ratio G / E).
    pub tangential_stiffness: f64,
}

/// The law of one pair of materials.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContactLaw {
    /// k_n of the pair (N/m).
    pub normal_stiffness: f64,
    /// k_t of the pair (N/m).
    pub tangential_stiffness: f64,
    /// Coulomb friction coefficient µ (seed 004 Table 1: 0.577; §4.1 also 1.73).
    pub friction: f64,
    /// Critical-damping ratio ζ of the normal dashpot c = 2ζ√(k_n m_eff) (0: none, the
    /// seed's choice between deformable bodies).
    pub damping_ratio: f64,
}

impl ContactLaw {
    /// The law between spheres of materials `a` and `b`: each sphere brings a half
    /// spring of stiffness 2k, in series, so a pair of like spheres has exactly the
    /// table's k and an unlike pair the harmonic mean 2 k_a k_b / (k_a + k_b).
    pub fn between(
        a: &SphereMaterial,
        b: &SphereMaterial,
        friction: f64,
        damping_ratio: f64,
    ) -> Self {
        let series = |x: f64, y: f64| {
            if x + y > 0.0 {
                2.0 * x * y / (x + y)
            } else {
                0.0
            }
        };
        ContactLaw {
            normal_stiffness: series(a.normal_stiffness, b.normal_stiffness),
            tangential_stiffness: series(a.tangential_stiffness, b.tangential_stiffness),
            friction,
            damping_ratio,
        }
    }

    /// The force on the second sphere of a pair and the updated tangential spring.
    ///
    /// `n` is the unit normal from the first sphere to the second, `overlap` δ > 0 the
    /// interpenetration, `v_rel` the second sphere's velocity relative to the first,
    /// `xi` the tangential spring elongation carried from the previous step (rotated
    /// here onto the current tangent plane, magnitude kept), `m_eff` the pair's reduced
    /// mass (for the dashpot), `dt` the step. Normal: f_n = k_n δ + c v_n, never
    /// tensile. Tangential: ξ += v_t dt, f_t = −k_t ξ, and where |f_t| > µ f_n the
    /// spring is cut back to the cone (the slider): ξ = −f_t / k_t with |f_t| = µ f_n.
    pub fn force(
        &self,
        n: [f64; 3],
        overlap: f64,
        v_rel: [f64; 3],
        xi: &mut [f64; 3],
        m_eff: f64,
        dt: f64,
    ) -> PairForce {
        let vn = dot(v_rel, n);
        let elastic = self.normal_stiffness * overlap;
        let c = 2.0 * self.damping_ratio * (self.normal_stiffness * m_eff).sqrt();
        let fn_mag = (elastic - c * vn).max(0.0);
        let damping_power = (fn_mag - elastic) * vn;
        // Rotate the carried spring onto the tangent plane, keeping its length.
        let len = norm(*xi);
        let mut t = sub(*xi, scale(n, dot(*xi, n)));
        let tl = norm(t);
        if tl > 0.0 {
            t = scale(t, len / tl);
        }
        let vt = sub(v_rel, scale(n, vn));
        let mut s = add(t, scale(vt, dt));
        let mut ft = scale(s, -self.tangential_stiffness);
        let limit = self.friction * fn_mag;
        let ft_len = norm(ft);
        let mut slip = 0.0;
        if ft_len > limit {
            let keep = if ft_len > 0.0 { limit / ft_len } else { 0.0 };
            let kept = scale(s, keep);
            // Energy the slider takes: the slip s − s' times the mean of the spring's
            // force at the step's start (t) and end (s'), ½ k_t (t + s')·(s − s'); the
            // work the integrator's trapezoid does on the spring is ½ k_t (t + s')·(s − t),
            // of which ½ k_t (|s'|² − |t|²) stays in it.
            slip = 0.5 * self.tangential_stiffness * dot(add(t, kept), sub(s, kept));
            s = kept;
            ft = scale(ft, keep);
        }
        *xi = s;
        PairForce {
            force: add(scale(n, fn_mag), ft),
            normal: fn_mag,
            spring_energy: 0.5 * elastic * overlap + 0.5 * self.tangential_stiffness * dot(s, s),
            slip_dissipated: slip,
            damping_dissipated: -damping_power * dt,
        }
    }
}

/// What one pair contact gives in a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairForce {
    /// Force on the second sphere (N); the first gets its opposite.
    pub force: [f64; 3],
    /// Normal force magnitude (N).
    pub normal: f64,
    /// ½ k_n δ² + ½ k_t |ξ|² (J).
    pub spring_energy: f64,
    /// Energy taken by the Coulomb slider this step (J): ½ k_t (t + s')·(s − s') with t
    /// the carried spring, s the trial one and s' the one kept on the cone.
    pub slip_dissipated: f64,
    /// Energy taken by the dashpot this step (J).
    pub damping_dissipated: f64,
}

impl PairForce {
    /// The force and its energies times `s`: the part one of n pairs carries when they
    /// share one spring (`SphereSet::shared_rest`, s = 1/n).
    pub fn scaled(self, s: f64) -> Self {
        PairForce {
            force: scale(self.force, s),
            normal: s * self.normal,
            spring_energy: s * self.spring_energy,
            slip_dissipated: s * self.slip_dissipated,
            damping_dissipated: s * self.damping_dissipated,
        }
    }
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
pub(crate) fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    const BALLAST: SphereMaterial = SphereMaterial {
        normal_stiffness: 1.613e9,
        tangential_stiffness: 0.672e9,
    };
    const SLEEPER: SphereMaterial = SphereMaterial {
        normal_stiffness: 2.390e9,
        tangential_stiffness: 1.024e9,
    };

    #[test]
    fn like_pairs_keep_the_table_value_and_unlike_pairs_are_in_series() {
        let like = ContactLaw::between(&BALLAST, &BALLAST, 0.577, 0.0);
        assert!((like.normal_stiffness - 1.613e9).abs() < 1.0);
        let unlike = ContactLaw::between(&BALLAST, &SLEEPER, 0.577, 0.0);
        let k = 2.0 * 1.613e9 * 2.390e9 / (1.613e9 + 2.390e9);
        assert!((unlike.normal_stiffness - k).abs() < 1.0);
    }

    #[test]
    fn the_slider_holds_the_force_on_the_coulomb_cone() {
        let law = ContactLaw::between(&BALLAST, &BALLAST, 0.5, 0.0);
        let mut xi = [0.0; 3];
        let n = [0.0, 0.0, 1.0];
        // Sticking: a small tangential motion loads the spring, f_t = −k_t ξ.
        let f = law.force(n, 1e-6, [1e-3, 0.0, 0.0], &mut xi, 1.0, 1e-6);
        assert!((f.force[0] + law.tangential_stiffness * 1e-9).abs() < 1e-9);
        assert!((f.force[2] - law.normal_stiffness * 1e-6).abs() < 1e-6);
        assert_eq!(f.slip_dissipated, 0.0);
        // Sliding: a large motion is cut back to µ f_n and dissipates.
        let f = law.force(n, 1e-6, [10.0, 0.0, 0.0], &mut xi, 1.0, 1e-6);
        let ft = (f.force[0].powi(2) + f.force[1].powi(2)).sqrt();
        assert!((ft - 0.5 * f.normal).abs() < 1e-9 * f.normal, "{ft}");
        assert!(f.slip_dissipated > 0.0);
        // The spring is parallel to the tangent plane and tension is never transmitted.
        let f = law.force(n, -1e-6, [0.0; 3], &mut xi, 1.0, 1e-6);
        assert_eq!(f.normal, 0.0);
        assert!(f.force.iter().all(|c| c.abs() < 1e-12));
    }

    /// With the normal fixed, the work the integrator's trapezoid does on the tangential
    /// spring, ½ (f_t + f_t')·(−v_t dt) summed over the steps, is what the spring holds
    /// at the end plus what the slider took, to round-off: loading into slip, sliding,
    /// turning, and unloading with the normal force falling (the cone shrinking under a
    /// spring at its edge, where the force-times-slip estimate µ f_n' |s − s'| missed
    /// ½ k_t (|t| − |s'|)² a step).
    #[test]
    fn the_slider_takes_what_the_spring_is_given_and_does_not_keep() {
        let law = ContactLaw::between(&BALLAST, &BALLAST, 1.73, 0.0);
        let n = [0.0, 0.0, 1.0];
        let (dt, mut xi) = (1e-6, [0.0; 3]);
        let (mut work, mut slip, mut force) = (0.0, 0.0, [0.0; 3]);
        for step in 0..400 {
            let s = step as f64;
            // Loading for 100 steps, then unloading to 1 % while sliding and turning.
            let overlap = 1e-6
                * if step < 100 {
                    1.0
                } else {
                    1.0 - 0.99 * (s - 100.0) / 300.0
                };
            let v = [0.3 * (0.02 * s).cos(), 0.2 * (0.013 * s).sin(), 0.0];
            let f = law.force(n, overlap, v, &mut xi, 1.0, dt);
            // The tangential parts of the forces at the step's start and end.
            let mean = [
                0.5 * (force[0] + f.force[0]),
                0.5 * (force[1] + f.force[1]),
                0.0,
            ];
            work -= dot(mean, v) * dt;
            slip += f.slip_dissipated;
            force = f.force;
        }
        let held = 0.5 * law.tangential_stiffness * dot(xi, xi);
        assert!(
            slip > 0.1 * work,
            "the test slides: slip {slip}, work {work}"
        );
        let error = (work - held - slip).abs();
        assert!(
            error < 1e-9 * work,
            "work {work} J, held {held} J, slip {slip} J"
        );
    }

    #[test]
    fn the_dashpot_dissipates_on_approach() {
        let law = ContactLaw::between(&BALLAST, &BALLAST, 0.5, 0.1);
        let mut xi = [0.0; 3];
        let f = law.force([0.0, 0.0, 1.0], 1e-6, [0.0, 0.0, -0.1], &mut xi, 1.0, 1e-6);
        let c = 0.2 * (law.normal_stiffness).sqrt();
        assert!((f.normal - (law.normal_stiffness * 1e-6 + c * 0.1)).abs() < 1e-6);
        assert!((f.damping_dissipated - c * 0.01 * 1e-6).abs() < 1e-12);
    }
}
