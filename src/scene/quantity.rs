//! Physical quantities in scene files: a value is either a plain number in SI units
//! (`density = 2350`) or a string with a unit (`density = "2350 kg/m^3"`). Each type
//! checks the dimension of the unit and stores SI; NaN and infinities are rejected.

use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize, Serializer};

use super::units::{parse_quantity, Dimension, UnitError};

/// A scalar that validation can check and print: a plain `f64` or a quantity type.
pub trait Measure: Copy {
    /// The value in SI units.
    fn si(self) -> f64;
    /// The SI unit symbol used in messages (empty for plain numbers).
    fn unit_symbol() -> &'static str;
}

impl Measure for f64 {
    fn si(self) -> f64 {
        self
    }
    fn unit_symbol() -> &'static str {
        ""
    }
}

/// Formats a value with its SI unit for messages: `-2350 kg/m^3`, `0.5`.
pub fn format_si<M: Measure>(value: M) -> String {
    let unit = M::unit_symbol();
    if unit.is_empty() {
        format!("{}", value.si())
    } else {
        format!("{} {unit}", value.si())
    }
}

/// What a quantity type accepts: used by the shared deserializer.
struct Kind {
    /// "a pressure", for "unit \"kg\" is not a pressure".
    article_name: &'static str,
    /// The units to suggest, e.g. "Pa, kPa, MPa or GPa".
    suggestion: &'static str,
    dimension: Dimension,
}

/// Reads a plain number (SI) or a string with a unit of the given kind.
struct QuantityVisitor(&'static Kind);

impl QuantityVisitor {
    fn finite<E: de::Error>(value: f64) -> Result<f64, E> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(E::custom(format!("must be a finite number, got {value}")))
        }
    }
}

impl Visitor<'_> for QuantityVisitor {
    type Value = f64;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} as a number in SI units or a string with a unit ({})",
            self.0.article_name, self.0.suggestion
        )
    }

    fn visit_f64<E: de::Error>(self, value: f64) -> Result<f64, E> {
        Self::finite(value)
    }

    fn visit_i64<E: de::Error>(self, value: i64) -> Result<f64, E> {
        Ok(value as f64)
    }

    fn visit_u64<E: de::Error>(self, value: u64) -> Result<f64, E> {
        Ok(value as f64)
    }

    fn visit_str<E: de::Error>(self, text: &str) -> Result<f64, E> {
        let kind = self.0;
        let parsed = parse_quantity(text).map_err(|err| match err {
            UnitError::UnknownUnit(unit) => E::custom(format!(
                "unknown unit \"{unit}\" in \"{text}\" (use {})",
                kind.suggestion
            )),
            UnitError::NotFinite => E::custom(format!("must be a finite number, got \"{text}\"")),
            other => E::custom(format!("{other}; expected {}", kind.suggestion)),
        })?;
        if parsed.dimension == kind.dimension {
            return Ok(parsed.si);
        }
        let unit = text
            .trim()
            .trim_start_matches(|c: char| c.is_ascii_digit() || "+-.eE".contains(c))
            .trim();
        if unit.is_empty() {
            Err(E::custom(format!(
                "\"{text}\" has no unit (use {})",
                kind.suggestion
            )))
        } else {
            Err(E::custom(format!(
                "unit \"{unit}\" is not {} (use {})",
                kind.article_name, kind.suggestion
            )))
        }
    }
}

macro_rules! quantities {
    ($(
        $(#[$doc:meta])*
        $name:ident, $kind:ident: $article:literal, [$l:literal, $m:literal, $t:literal, $a:literal],
        si $si:literal, use $suggestion:literal;
    )*) => {$(
        const $kind: Kind = Kind {
            article_name: $article,
            suggestion: $suggestion,
            dimension: Dimension::new($l, $m, $t, $a),
        };

        $(#[$doc])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
        pub struct $name(f64);

        impl $name {
            /// The dimension of this quantity (exponents of m, kg, s, rad).
            pub const DIMENSION: Dimension = Dimension::new($l, $m, $t, $a);

            /// A value given in SI units.
            pub const fn from_si(value: f64) -> Self {
                $name(value)
            }

            /// The value in SI units.
            pub const fn si(self) -> f64 {
                self.0
            }

            /// Parses a string such as those accepted in scene files; the error is
            /// the reason, without a key.
            pub fn parse(text: &str) -> Result<Self, String> {
                QuantityVisitor(&$kind)
                    .visit_str::<de::value::Error>(text)
                    .map($name)
                    .map_err(|err| err.to_string())
            }
        }

        impl Measure for $name {
            fn si(self) -> f64 {
                self.0
            }
            fn unit_symbol() -> &'static str {
                $si
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{} {}", self.0, $si)
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                deserializer.deserialize_any(QuantityVisitor(&$kind)).map($name)
            }
        }

        /// Serialized as the plain SI number, which reads back unchanged.
        impl Serialize for $name {
            fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_f64(self.0)
            }
        }
    )*};
}

quantities! {
    /// A length in metres (m, mm, cm, km, µm).
    Length, LENGTH: "a length", [1, 0, 0, 0], si "m", use "m, mm, cm or km";
    /// A duration in seconds (s, ms, µs; min and h for wall-clock spans).
    Time, TIME: "a time", [0, 0, 1, 0], si "s", use "s, ms, us, min or h";
    /// A mass in kilograms (kg, g).
    Mass, MASS: "a mass", [0, 1, 0, 0], si "kg", use "kg or g";
    /// A mass density in kg/m³ (kg/m^3, g/cm^3).
    Density, DENSITY: "a density", [-3, 1, 0, 0], si "kg/m^3", use "kg/m^3 or g/cm^3";
    /// A pressure, stress or elastic modulus in pascals (Pa, kPa, MPa, GPa, N/m^2).
    Pressure, PRESSURE: "a pressure", [-1, 1, -2, 0], si "Pa", use "Pa, kPa, MPa or GPa";
    /// A force in newtons (N, kN, MN).
    Force, FORCE: "a force", [1, 1, -2, 0], si "N", use "N, kN or MN";
    /// A frequency in hertz (Hz, kHz, 1/s).
    Frequency, FREQUENCY: "a frequency", [0, 0, -1, 0], si "Hz", use "Hz or kHz";
    /// A speed in m/s (m/s, mm/s).
    Velocity, VELOCITY: "a velocity", [1, 0, -1, 0], si "m/s", use "m/s or mm/s";
    /// An acceleration in m/s² (m/s^2).
    Acceleration, ACCELERATION: "an acceleration", [1, 0, -2, 0], si "m/s^2", use "m/s^2";
    /// A plane angle, stored in radians (rad, deg); a plain number is in radians.
    Angle, ANGLE: "an angle", [0, 0, 0, 1], si "rad", use "rad or deg";
    /// A dynamic viscosity in Pa·s (Pa*s, Pa s, MPa*s).
    Viscosity, VISCOSITY: "a viscosity", [-1, 1, -1, 0], si "Pa*s", use "Pa*s, kPa*s or MPa*s";
    /// A spring stiffness in N/m (N/m, kN/mm, MN/m).
    Stiffness, STIFFNESS: "a stiffness", [0, 1, -2, 0], si "N/m", use "N/m, kN/mm or MN/m";
    /// A stiffness per unit area (bedding modulus) in N/m³ (N/m^3, MN/m^3).
    StiffnessPerArea, STIFFNESS_PER_AREA: "a stiffness per area", [-2, 1, -2, 0],
        si "N/m^3", use "N/m^3 or MN/m^3";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    struct Sample {
        value: Pressure,
    }

    fn read<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, String> {
        toml::from_str(text).map_err(|err| err.message().to_string())
    }

    #[test]
    fn plain_numbers_are_si() {
        let s: Sample = read("value = 3").unwrap();
        assert_eq!(s.value.si(), 3.0);
        let s: Sample = read("value = 2.5e9").unwrap();
        assert_eq!(s.value.si(), 2.5e9);
        let s: Sample = read("value = \"30 GPa\"").unwrap();
        assert_eq!(s.value.si(), 30e9);
    }

    #[test]
    fn every_type_reads_its_units() {
        let eps = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
        assert!(eps(Length::parse("10.5 mm").unwrap().si(), 10.5e-3));
        assert!(eps(Time::parse("2e-4 s").unwrap().si(), 2e-4));
        assert!(eps(Mass::parse("500 g").unwrap().si(), 0.5));
        assert!(eps(Density::parse("2350 kg/m^3").unwrap().si(), 2350.0));
        assert!(eps(Pressure::parse("30 GPa").unwrap().si(), 30e9));
        assert!(eps(Pressure::parse("1 N/m^2").unwrap().si(), 1.0));
        assert!(eps(Force::parse("20 kN").unwrap().si(), 2e4));
        assert!(eps(Frequency::parse("35 Hz").unwrap().si(), 35.0));
        assert!(eps(Velocity::parse("5 mm/s").unwrap().si(), 5e-3));
        assert!(eps(Acceleration::parse("9.81 m/s^2").unwrap().si(), 9.81));
        assert!(eps(
            Angle::parse("30 deg").unwrap().si(),
            std::f64::consts::PI / 6.0
        ));
        assert!(eps(Viscosity::parse("3 MPa*s").unwrap().si(), 3e6));
        assert!(eps(Viscosity::parse("3 Pa s").unwrap().si(), 3.0));
        assert!(eps(Stiffness::parse("80 kN/mm").unwrap().si(), 80e6));
        assert!(eps(Stiffness::parse("80 MN/m").unwrap().si(), 80e6));
        assert!(eps(
            StiffnessPerArea::parse("100 MN/m^3").unwrap().si(),
            100e6
        ));
    }

    #[test]
    fn wrong_dimension_names_the_unit_and_the_fix() {
        assert_eq!(
            Pressure::parse("30 kg").unwrap_err(),
            "unit \"kg\" is not a pressure (use Pa, kPa, MPa or GPa)"
        );
        assert_eq!(
            Length::parse("3 s").unwrap_err(),
            "unit \"s\" is not a length (use m, mm, cm or km)"
        );
        assert_eq!(
            Angle::parse("3 m").unwrap_err(),
            "unit \"m\" is not an angle (use rad or deg)"
        );
        assert_eq!(
            Frequency::parse("3 rad/s").unwrap_err(),
            "unit \"rad/s\" is not a frequency (use Hz or kHz)"
        );
        assert_eq!(
            Density::parse("2350").unwrap_err(),
            "\"2350\" has no unit (use kg/m^3 or g/cm^3)"
        );
    }

    #[test]
    fn bad_text_and_non_finite_values_are_rejected() {
        assert_eq!(
            Pressure::parse("abc").unwrap_err(),
            "\"abc\" is not a number with a unit (e.g. \"2.5 mm\"); expected Pa, kPa, MPa or GPa"
        );
        assert_eq!(
            Pressure::parse("3 psi").unwrap_err(),
            "unknown unit \"psi\" in \"3 psi\" (use Pa, kPa, MPa or GPa)"
        );
        assert!(Pressure::parse("1e400 Pa").unwrap_err().contains("finite"));
        let err = read::<Sample>("value = nan").unwrap_err();
        assert_eq!(err, "must be a finite number, got NaN");
        let err = read::<Sample>("value = inf").unwrap_err();
        assert_eq!(err, "must be a finite number, got inf");
        let err = read::<Sample>("value = true").unwrap_err();
        assert!(err.contains("a pressure as a number in SI units"), "{err}");
    }

    #[test]
    fn display_and_serialize_in_si() {
        let density = Density::parse("2.35 g/cm^3").unwrap();
        assert_eq!(format_si(density), "2350 kg/m^3");
        assert_eq!(format_si(0.5), "0.5");
        assert_eq!(
            serde_json::to_value(density).unwrap(),
            serde_json::json!(2350.0)
        );
        assert_eq!(Angle::from_si(1.0).to_string(), "1 rad");
    }
}
