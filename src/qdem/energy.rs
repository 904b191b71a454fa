//! Energy bookkeeping of a QDEM run: what is stored, what was dissipated, what was put in.

/// Energy terms of a run (J). The balance
/// `kinetic + strain + viscous_dissipated + damping_dissipated − external_work − initial`
/// is zero for the exact dynamics; the explicit scheme leaves an O(dt²) residue.
///
/// The strain energy is Σ V_0 (λ/2 (tr ε)² + µ ε:ε) with ε = (B − I)/2: the potential
/// of the paper's Hooke law at small strain. Eq. 2 applied to a finite strain is not
/// exactly hyperelastic, so at strains ε the balance also carries an O(ε) relative term.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Energies {
    /// ½ Σ m v² at the current step.
    pub kinetic: f64,
    /// Elastic strain energy at the current positions.
    pub strain: f64,
    /// ∫ Σ V T_D : D dt, energy dissipated by the Kelvin–Voigt viscosity.
    pub viscous_dissipated: f64,
    /// Energy removed by the numerical damping option (mass-proportional damping or the
    /// kinetic-energy resets of dynamic relaxation).
    pub damping_dissipated: f64,
    /// ∫ Σ f_ext · v dt: work of the group loads and of gravity.
    pub external_work: f64,
    /// kinetic + strain at the start of the run.
    pub initial: f64,
}

impl Energies {
    /// kinetic + strain.
    pub fn mechanical(&self) -> f64 {
        self.kinetic + self.strain
    }

    /// kinetic + strain + dissipated − external work − initial (J).
    pub fn balance_error(&self) -> f64 {
        self.kinetic + self.strain + self.viscous_dissipated + self.damping_dissipated
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
