//! An isotropic (visco)elastic material as written in scene files, with its checks and
//! the derived moduli that the solvers use.

use serde::{Deserialize, Serialize};

use super::quantity::{Density, Pressure, Velocity, Viscosity};
use super::validate::{Validate, Validator};

/// An isotropic linear elastic material with optional Kelvin–Voigt viscosity.
///
/// ```toml
/// [material]
/// name = "concrete"
/// density = "2350 kg/m^3"
/// young_modulus = "30 GPa"
/// poisson = 0.2
/// shear_viscosity = "1 MPa*s"   # optional
/// ```
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// A name for reports and output files.
    pub name: String,
    /// Mass density ρ.
    pub density: Density,
    /// Young's modulus E.
    pub young_modulus: Pressure,
    /// Poisson's ratio ν, with -1 < ν < 0.5.
    pub poisson: f64,
    /// Shear viscosity µ_D of the Kelvin–Voigt stress `2 µ_D D`; none means elastic.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_viscosity: Option<Viscosity>,
    /// Bulk viscosity κ_D; the viscous stress is `(κ_D − 2µ_D/3) tr D I + 2 µ_D D`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bulk_viscosity: Option<Viscosity>,
}

impl Validate for Material {
    fn validate(&self, v: &mut Validator) {
        v.check("name", !self.name.trim().is_empty(), "must not be empty");
        v.positive("density", self.density);
        v.positive("young_modulus", self.young_modulus);
        v.poisson("poisson", self.poisson);
        if let Some(mu) = self.shear_viscosity {
            v.non_negative("shear_viscosity", mu);
        }
        if let Some(kappa) = self.bulk_viscosity {
            v.non_negative("bulk_viscosity", kappa);
        }
    }
}

impl Material {
    /// Shear modulus µ = E / (2(1 + ν)), in Pa.
    pub fn shear_modulus(&self) -> f64 {
        self.young_modulus.si() / (2.0 * (1.0 + self.poisson))
    }

    /// First Lamé parameter λ = E ν / ((1 + ν)(1 − 2ν)), in Pa.
    pub fn lame_lambda(&self) -> f64 {
        let nu = self.poisson;
        self.young_modulus.si() * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    }

    /// Bulk modulus K = E / (3(1 − 2ν)), in Pa.
    pub fn bulk_modulus(&self) -> f64 {
        self.young_modulus.si() / (3.0 * (1.0 - 2.0 * self.poisson))
    }

    /// Dilatational (P-wave) speed c_d = √((λ + 2µ)/ρ), used for stable time steps.
    pub fn dilatational_wave_speed(&self) -> Velocity {
        let p_modulus = self.lame_lambda() + 2.0 * self.shear_modulus();
        Velocity::from_si((p_modulus / self.density.si()).sqrt())
    }

    /// Viscous Lamé pair (λ_D, µ_D) in Pa·s; zero where a viscosity is not given.
    pub fn viscous_lame(&self) -> (f64, f64) {
        let mu = self.shear_viscosity.map_or(0.0, Viscosity::si);
        let kappa = self.bulk_viscosity.map_or(0.0, Viscosity::si);
        (kappa - 2.0 * mu / 3.0, mu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn concrete() -> Material {
        toml::from_str(
            r#"
            name = "concrete"
            density = "2350 kg/m^3"
            young_modulus = "30 GPa"
            poisson = 0.2
            shear_viscosity = "1 MPa*s"
            "#,
        )
        .unwrap()
    }

    #[test]
    fn derived_moduli() {
        let m = concrete();
        assert_eq!(m.shear_modulus(), 12.5e9);
        assert!((m.lame_lambda() - 30e9 * 0.2 / (1.2 * 0.6)).abs() < 1e-3);
        assert!((m.bulk_modulus() - 30e9 / 1.8).abs() < 1e-3);
        let c = m.dilatational_wave_speed().si();
        assert!((c * c * 2350.0 - (m.lame_lambda() + 25e9)).abs() < 1.0);
        let (lambda_d, mu_d) = m.viscous_lame();
        assert_eq!(mu_d, 1e6);
        assert!((lambda_d + 2e6 / 3.0).abs() < 1e-9);
    }

    #[test]
    fn validation_names_each_key() {
        let mut v = Validator::new();
        concrete().validate(&mut v);
        assert!(v.finish().is_ok());

        let mut bad = concrete();
        bad.name = " ".into();
        bad.density = Density::from_si(-1.0);
        bad.young_modulus = Pressure::from_si(0.0);
        bad.poisson = 0.5;
        bad.bulk_viscosity = Some(Viscosity::from_si(-3.0));
        let mut v = Validator::new();
        v.nested("material", &bad);
        assert_eq!(
            v.problems(),
            [
                "key material.name: must not be empty",
                "key material.density: must be positive, got -1 kg/m^3",
                "key material.young_modulus: must be positive, got 0 Pa",
                "key material.poisson: Poisson ratio must be greater than -1 and less than 0.5, got 0.5",
                "key material.bulk_viscosity: must not be negative, got -3 Pa*s",
            ]
        );
    }
}
