//! Kelvin–Voigt material of seed 004 §2.1–2.2: Hooke elasticity (eq. 2) in parallel with
//! a linear viscous fluid (eq. 7), given by the engineering constants a scene names.

use crate::{Error, Result};

/// An isotropic Kelvin–Voigt material as a user gives it (SI units).
///
/// The paper's parameters map onto the Lamé-type constants of eq. 2 and eq. 7 as
/// - λ_E = E ν / ((1 + ν)(1 − 2ν)), µ_E = E / (2(1 + ν));
/// - µ_D = `shear_viscosity`, and since the paper calls λ_D + 2/3 µ_D the bulk viscosity,
///   λ_D = `bulk_viscosity` − 2/3 `shear_viscosity` (negative when the bulk viscosity is
///   zero, as in the paper's creep test: then a pure volume change meets no viscous stress).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QdemMaterial {
    /// Mass density ρ in kg/m³.
    pub density: f64,
    /// Young's modulus E in Pa.
    pub young_modulus: f64,
    /// Poisson's ratio ν (−1 < ν < 0.5).
    pub poisson_ratio: f64,
    /// Shear viscosity µ_D in Pa·s (0 for a purely elastic body).
    pub shear_viscosity: f64,
    /// Bulk viscosity κ_D = λ_D + 2/3 µ_D in Pa·s.
    pub bulk_viscosity: f64,
}

impl QdemMaterial {
    /// A purely elastic material (both viscosities zero).
    pub fn elastic(density: f64, young_modulus: f64, poisson_ratio: f64) -> Self {
        QdemMaterial {
            density,
            young_modulus,
            poisson_ratio,
            shear_viscosity: 0.0,
            bulk_viscosity: 0.0,
        }
    }

    /// Checks the ranges; the error names the parameter and its value.
    pub fn validate(&self) -> Result<()> {
        let bad = |name: &str, value: f64, why: &str| {
            Err(Error::Message(format!(
                "QDEM material: {name} = {value} {why}"
            )))
        };
        if !(self.density.is_finite() && self.density > 0.0) {
            return bad("density", self.density, "must be positive (kg/m³)");
        }
        if !(self.young_modulus.is_finite() && self.young_modulus > 0.0) {
            return bad("young_modulus", self.young_modulus, "must be positive (Pa)");
        }
        if !(self.poisson_ratio.is_finite()
            && self.poisson_ratio > -1.0
            && self.poisson_ratio < 0.5)
        {
            return bad(
                "poisson_ratio",
                self.poisson_ratio,
                "must lie strictly between -1 and 0.5",
            );
        }
        if !(self.shear_viscosity.is_finite() && self.shear_viscosity >= 0.0) {
            return bad(
                "shear_viscosity",
                self.shear_viscosity,
                "must be zero or positive (Pa·s)",
            );
        }
        if !(self.bulk_viscosity.is_finite() && self.bulk_viscosity >= 0.0) {
            return bad(
                "bulk_viscosity",
                self.bulk_viscosity,
                "must be zero or positive (Pa·s)",
            );
        }
        Ok(())
    }

    /// First Lamé constant λ_E (Pa).
    pub fn lame_lambda(&self) -> f64 {
        let nu = self.poisson_ratio;
        self.young_modulus * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Shear modulus µ_E (Pa).
    pub fn lame_mu(&self) -> f64 {
        self.young_modulus / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Viscous λ_D = κ_D − 2/3 µ_D (Pa·s).
    pub fn viscous_lambda(&self) -> f64 {
        self.bulk_viscosity - 2.0 / 3.0 * self.shear_viscosity
    }

    /// Viscous µ_D (Pa·s).
    pub fn viscous_mu(&self) -> f64 {
        self.shear_viscosity
    }

    /// Dilatational (P-) wave speed c_d = √((λ + 2µ)/ρ) in m/s.
    pub fn dilatational_wave_speed(&self) -> f64 {
        ((self.lame_lambda() + 2.0 * self.lame_mu()) / self.density).sqrt()
    }

    /// The largest viscous time of the material (s): max((λ_D + 2µ_D)/(λ + 2µ), µ_D/µ).
    /// For proportional viscosity (λ_D/λ = µ_D/µ = τ) it is τ and the damping matrix is
    /// τ K; otherwise the larger ratio bounds the damping of every mode from above.
    pub fn viscous_time(&self) -> f64 {
        let dilatational = (self.viscous_lambda() + 2.0 * self.viscous_mu())
            / (self.lame_lambda() + 2.0 * self.lame_mu());
        let shear = self.viscous_mu() / self.lame_mu();
        dilatational.max(shear).max(0.0)
    }
}

/// The constants the element kernel reads (one per material, shared by its tetra).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ElementMaterial {
    pub density: f64,
    pub lambda: f64,
    pub mu: f64,
    pub viscous_lambda: f64,
    pub viscous_mu: f64,
    /// False when both viscosities are zero: the kernel skips the velocity gradient.
    pub viscous: bool,
}

impl From<&QdemMaterial> for ElementMaterial {
    fn from(m: &QdemMaterial) -> Self {
        ElementMaterial {
            density: m.density,
            lambda: m.lame_lambda(),
            mu: m.lame_mu(),
            viscous_lambda: m.viscous_lambda(),
            viscous_mu: m.viscous_mu(),
            viscous: m.shear_viscosity != 0.0 || m.bulk_viscosity != 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lame_constants_of_the_paper_concrete() {
        let m = QdemMaterial::elastic(2350.0, 45e9, 0.167);
        // E = µ(3λ + 2µ)/(λ + µ) and ν = λ / (2(λ + µ)) recover the inputs.
        let (l, mu) = (m.lame_lambda(), m.lame_mu());
        assert!((mu * (3.0 * l + 2.0 * mu) / (l + mu) / 45e9 - 1.0).abs() < 1e-14);
        assert!((l / (2.0 * (l + mu)) / 0.167 - 1.0).abs() < 1e-14);
    }

    #[test]
    fn bulk_viscosity_maps_to_viscous_lambda() {
        let m = QdemMaterial {
            shear_viscosity: 3.0,
            bulk_viscosity: 5.0,
            ..QdemMaterial::elastic(1.0, 1.0, 0.25)
        };
        assert!((m.viscous_lambda() + 2.0 / 3.0 * m.viscous_mu() - 5.0).abs() < 1e-15);
    }

    #[test]
    fn validation_names_the_parameter() {
        let m = QdemMaterial::elastic(2350.0, 45e9, 0.5);
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("poisson_ratio"), "{e}");
    }
}
