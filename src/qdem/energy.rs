//! Energy bookkeeping of a QDEM run: what is stored, what was dissipated, what was put in.

/// Energy terms of a run (J). The balance
/// `kinetic − verlet_correction + strain + viscous_dissipated + damping_dissipated
///  − external_work − initial` is zero for the exact dynamics.
///
/// Velocity Verlet conserves exactly (for a linear elastic body, with the trapezoidal
/// work of the loads) not ½ Σ m v_n² but ½ Σ m v_{n−½}·v_{n+½} = kinetic −
/// `verlet_correction`, with `verlet_correction` = dt²/8 Σ m |a_n|²: a bounded O(dt²)
/// term that is large only for modes near the stability limit. Subtracting it leaves
/// as balance error the genuine non-conservation (viscous and damping quadrature,
/// finite-strain effects, round-off).
///
/// The strain energy is Σ V_0 (λ/2 (tr ε)² + µ ε:ε) with ε = (B − I)/2: the potential
/// of the paper's Hooke law at small strain. Eq. 2 applied to a finite strain is not
/// exactly hyperelastic, so at strains ε the balance also carries an O(ε) relative term.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Energies {
    /// ½ Σ m v² at the current step.
    pub kinetic: f64,
    /// dt²/8 Σ m |a|² at the current step (see above).
    pub verlet_correction: f64,
    /// Elastic strain energy at the current positions, with the group springs'
    /// ½ k ū² ([`super::GroupSpring`]).
    pub strain: f64,
    /// ∫ Σ V T_D : D dt, energy dissipated by the Kelvin–Voigt viscosity.
    pub viscous_dissipated: f64,
    /// Energy removed by the numerical damping option (mass-proportional damping or the
    /// kinetic-energy resets of dynamic relaxation).
    pub damping_dissipated: f64,
    /// ∫ Σ f_ext · v dt: work of the group loads, of gravity and of a caller's force
    /// hook (contacts).
    pub external_work: f64,
    /// The part of `external_work` done by the force hook ([`super::QdemSolver::step_with`]).
    pub hook_work: f64,
    /// kinetic − verlet_correction + strain at the start of the run.
    pub initial: f64,
}

impl Energies {
    /// kinetic + strain.
    pub fn mechanical(&self) -> f64 {
        self.kinetic + self.strain
    }

    /// kinetic − verlet_correction + strain + dissipated − external work − initial (J).
    pub fn balance_error(&self) -> f64 {
        self.kinetic - self.verlet_correction
            + self.strain
            + self.viscous_dissipated
            + self.damping_dissipated
            - self.external_work
            - self.initial
    }

    /// |balance error| over the energy scale of the run (the largest of the energy put
    /// in and the stored and dissipated energies); 0 for a run with no energy at all.
    pub fn relative_balance_error(&self) -> f64 {
        let scale = (self.initial + self.external_work.abs())
            .max(self.mechanical())
            .max(self.viscous_dissipated + self.damping_dissipated);
        if scale > 0.0 {
            self.balance_error().abs() / scale
        } else {
            0.0
        }
    }
}
