//! A compact parser for numbers with units, such as `"30 GPa"`, `"2350 kg/m^3"` or
//! `"35 Hz"`: the unit expression becomes an SI factor and a dimension vector, so a
//! quantity type only has to compare dimensions and multiply.

use std::fmt;

/// Exponents of the base dimensions (length, mass, time, angle) of a unit.
///
/// Angle is kept apart from the dimensionless numbers so that `"30 deg"` cannot be
/// given where a plain ratio is expected, and `"3 m"` cannot be given as an angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Dimension {
    /// Exponent of length (m).
    pub length: i8,
    /// Exponent of mass (kg).
    pub mass: i8,
    /// Exponent of time (s).
    pub time: i8,
    /// Exponent of plane angle (rad).
    pub angle: i8,
}

impl Dimension {
    /// A dimension from its exponents of length, mass, time and angle.
    pub const fn new(length: i8, mass: i8, time: i8, angle: i8) -> Self {
        Dimension {
            length,
            mass,
            time,
            angle,
        }
    }

    /// The dimension of a pure number.
    pub const NONE: Dimension = Dimension::new(0, 0, 0, 0);

    fn scaled_add(self, other: Dimension, power: i8) -> Dimension {
        Dimension {
            length: self.length + other.length * power,
            mass: self.mass + other.mass * power,
            time: self.time + other.time * power,
            angle: self.angle + other.angle * power,
        }
    }
}

/// A parsed value: the number in SI units and the dimension of its unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Parsed {
    /// The value converted to SI (m, kg, s, rad and their products).
    pub si: f64,
    /// The dimension of the unit that was written.
    pub dimension: Dimension,
}

/// Why a string could not be read as a number with a unit.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitError {
    /// The string does not start with a number.
    NotANumber(String),
    /// A unit symbol (or its exponent) is not known.
    UnknownUnit(String),
    /// The number is NaN or infinite.
    NotFinite,
}

impl fmt::Display for UnitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitError::NotANumber(text) => {
                write!(
                    f,
                    "\"{text}\" is not a number with a unit (e.g. \"2.5 mm\")"
                )
            }
            UnitError::UnknownUnit(unit) => write!(f, "unknown unit \"{unit}\""),
            UnitError::NotFinite => write!(f, "must be a finite number"),
        }
    }
}

/// Unit symbols that take no prefix: (symbol, SI factor, dimension).
const FIXED_UNITS: &[(&str, f64, Dimension)] = &[
    // Wall-clock spans (checkpoint intervals): minutes and hours.
    ("min", 60.0, Dimension::new(0, 0, 1, 0)),
    ("h", 3600.0, Dimension::new(0, 0, 1, 0)),
    (
        "deg",
        std::f64::consts::PI / 180.0,
        Dimension::new(0, 0, 0, 1),
    ),
    (
        "°",
        std::f64::consts::PI / 180.0,
        Dimension::new(0, 0, 0, 1),
    ),
    ("1", 1.0, Dimension::NONE),
];

/// Unit symbols that accept an SI prefix: (symbol, SI factor, dimension).
const PREFIXABLE_UNITS: &[(&str, f64, Dimension)] = &[
    ("m", 1.0, Dimension::new(1, 0, 0, 0)),
    ("g", 1e-3, Dimension::new(0, 1, 0, 0)),
    ("s", 1.0, Dimension::new(0, 0, 1, 0)),
    ("Hz", 1.0, Dimension::new(0, 0, -1, 0)),
    ("N", 1.0, Dimension::new(1, 1, -2, 0)),
    ("Pa", 1.0, Dimension::new(-1, 1, -2, 0)),
    ("rad", 1.0, Dimension::new(0, 0, 0, 1)),
];

/// SI prefixes understood before a prefixable unit.
const PREFIXES: &[(char, f64)] = &[
    ('G', 1e9),
    ('M', 1e6),
    ('k', 1e3),
    ('c', 1e-2),
    ('m', 1e-3),
    ('u', 1e-6),
    ('µ', 1e-6),
    ('μ', 1e-6),
    ('n', 1e-9),
];

/// Parses `"<number> <unit expression>"`, e.g. `"2e-4 s"`, `"10.5mm"`, `"1.2 Pa*s"`,
/// `"2350 kg/m^3"`, `"50 kN/mm"`. Factors are separated by `*`, `·` or spaces; every
/// factor after a `/` is in the denominator; `^` gives an integer exponent. A number
/// without a unit is dimensionless.
pub fn parse_quantity(text: &str) -> Result<Parsed, UnitError> {
    let trimmed = text.trim();
    let number_len = number_prefix_len(trimmed);
    if number_len == 0 {
        return Err(UnitError::NotANumber(text.to_string()));
    }
    let value: f64 = trimmed[..number_len]
        .parse()
        .map_err(|_| UnitError::NotANumber(text.to_string()))?;
    if !value.is_finite() {
        return Err(UnitError::NotFinite);
    }
    let (factor, dimension) = parse_unit(trimmed[number_len..].trim())?;
    let si = value * factor;
    if !si.is_finite() {
        return Err(UnitError::NotFinite);
    }
    Ok(Parsed { si, dimension })
}

/// Parses a unit expression alone (e.g. `"kN/mm"`) into its SI factor and dimension.
/// The empty string is the dimensionless unit 1.
pub fn parse_unit(unit: &str) -> Result<(f64, Dimension), UnitError> {
    let mut factor = 1.0;
    let mut dimension = Dimension::NONE;
    for (part_index, part) in unit.split('/').enumerate() {
        let sign: i8 = if part_index == 0 { 1 } else { -1 };
        let factors: Vec<&str> = part
            .split(|c: char| c == '*' || c == '·' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        // "N/" or "/m" or "a//b" are typos, not units.
        if factors.is_empty() && (part_index > 0 || unit.contains('/')) {
            return Err(UnitError::UnknownUnit(unit.to_string()));
        }
        for symbol_with_power in factors {
            let (symbol, power) = split_power(symbol_with_power)
                .ok_or_else(|| UnitError::UnknownUnit(symbol_with_power.to_string()))?;
            let (symbol_factor, symbol_dimension) =
                lookup_symbol(symbol).ok_or_else(|| UnitError::UnknownUnit(symbol.to_string()))?;
            let power = power * sign;
            factor *= symbol_factor.powi(i32::from(power));
            dimension = dimension.scaled_add(symbol_dimension, power);
        }
    }
    Ok((factor, dimension))
}

/// Length in bytes of the leading decimal number of `text` (0 if there is none).
fn number_prefix_len(text: &str) -> usize {
    let bytes = text.as_bytes();
    let mut i = 0;
    if matches!(bytes.first(), Some(b'+' | b'-')) {
        i += 1;
    }
    let digits_start = i;
    while i < bytes.len() && bytes[i].is_ascii_digit() {
        i += 1;
    }
    let mut digit_count = i - digits_start;
    if i < bytes.len() && bytes[i] == b'.' {
        i += 1;
        let fraction_start = i;
        while i < bytes.len() && bytes[i].is_ascii_digit() {
            i += 1;
        }
        digit_count += i - fraction_start;
    }
    if digit_count == 0 {
        return 0;
    }
    // An exponent only when digits follow, so that "2 e" is not half read.
    if i < bytes.len() && (bytes[i] == b'e' || bytes[i] == b'E') {
        let mut j = i + 1;
        if j < bytes.len() && (bytes[j] == b'+' || bytes[j] == b'-') {
            j += 1;
        }
        let exponent_start = j;
        while j < bytes.len() && bytes[j].is_ascii_digit() {
            j += 1;
        }
        if j > exponent_start {
            i = j;
        }
    }
    i
}

/// Splits `"m^3"` into `("m", 3)`; a symbol without `^` has power 1.
fn split_power(symbol: &str) -> Option<(&str, i8)> {
    match symbol.split_once('^') {
        None => Some((symbol, 1)),
        Some((base, power)) => {
            let power: i8 = power.parse().ok()?;
            (!base.is_empty() && power != 0 && power.abs() <= 9).then_some((base, power))
        }
    }
}

/// The SI factor and dimension of one unit symbol, with an optional SI prefix.
fn lookup_symbol(symbol: &str) -> Option<(f64, Dimension)> {
    let find = |table: &[(&str, f64, Dimension)], s: &str| {
        table
            .iter()
            .find(|(name, _, _)| *name == s)
            .map(|&(_, factor, dimension)| (factor, dimension))
    };
    if let Some(found) = find(FIXED_UNITS, symbol).or_else(|| find(PREFIXABLE_UNITS, symbol)) {
        return Some(found);
    }
    let mut chars = symbol.chars();
    let prefix = chars.next()?;
    let (_, prefix_factor) = PREFIXES.iter().find(|(p, _)| *p == prefix)?;
    let (factor, dimension) = find(PREFIXABLE_UNITS, chars.as_str())?;
    Some((prefix_factor * factor, dimension))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn si(text: &str) -> f64 {
        parse_quantity(text).unwrap().si
    }

    fn dim(text: &str) -> Dimension {
        parse_quantity(text).unwrap().dimension
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
    }

    #[test]
    fn numbers_in_every_form() {
        assert_eq!(si("3"), 3.0);
        assert_eq!(si(" -2.5 "), -2.5);
        assert_eq!(si("+.5"), 0.5);
        assert_eq!(si("5."), 5.0);
        assert!(close(si("2e-4 s"), 2e-4));
        assert!(close(si("1.5E3 Pa"), 1.5e3));
        assert!(close(si("10.5mm"), 10.5e-3));
        assert_eq!(dim("3"), Dimension::NONE);
    }

    #[test]
    fn every_base_unit_and_prefix() {
        assert!(close(si("2 m"), 2.0));
        assert!(close(si("2 km"), 2e3));
        assert!(close(si("2 cm"), 2e-2));
        assert!(close(si("2 mm"), 2e-3));
        assert!(close(si("2 um"), 2e-6));
        assert!(close(si("2 µm"), 2e-6));
        assert!(close(si("2 nm"), 2e-9));
        assert!(close(si("2 g"), 2e-3));
        assert!(close(si("2 kg"), 2.0));
        assert!(close(si("2 Mg"), 2e3));
        assert!(close(si("2 ms"), 2e-3));
        assert!(close(si("2 us"), 2e-6));
        assert!(close(si("30 min"), 1800.0));
        assert!(close(si("1.5 h"), 5400.0));
        assert!(close(si("35 Hz"), 35.0));
        assert!(close(si("2 kHz"), 2e3));
        assert!(close(si("3 N"), 3.0));
        assert!(close(si("3 kN"), 3e3));
        assert!(close(si("3 MN"), 3e6));
        assert!(close(si("4 Pa"), 4.0));
        assert!(close(si("4 kPa"), 4e3));
        assert!(close(si("4 MPa"), 4e6));
        assert!(close(si("30 GPa"), 30e9));
        assert!(close(si("1 rad"), 1.0));
        assert!(close(si("5 mrad"), 5e-3));
        assert!(close(si("30 deg"), std::f64::consts::PI / 6.0));
        assert!(close(si("90°"), std::f64::consts::FRAC_PI_2));
    }

    #[test]
    fn compound_units() {
        assert!(close(si("2350 kg/m^3"), 2350.0));
        assert_eq!(dim("2350 kg/m^3"), Dimension::new(-3, 1, 0, 0));
        assert!(close(si("2.35 g/cm^3"), 2350.0));
        assert!(close(si("5 N/m^2"), 5.0));
        assert_eq!(dim("5 N/m^2"), dim("5 Pa"));
        assert!(close(si("3 mm/s"), 3e-3));
        assert_eq!(dim("3 m/s"), Dimension::new(1, 0, -1, 0));
        assert!(close(si("9.81 m/s^2"), 9.81));
        assert_eq!(dim("9.81 m/s^2"), Dimension::new(1, 0, -2, 0));
        assert!(close(si("9.81 m*s^-2"), 9.81));
        assert!(close(si("2 Pa*s"), 2.0));
        assert!(close(si("2 Pa s"), 2.0));
        assert!(close(si("2 Pa·s"), 2.0));
        assert!(close(si("2 MPa*s"), 2e6));
        assert_eq!(dim("2 Pa s"), Dimension::new(-1, 1, -1, 0));
        assert!(close(si("50 kN/mm"), 50e6));
        assert!(close(si("50 MN/m"), 50e6));
        assert_eq!(dim("50 N/m"), Dimension::new(0, 1, -2, 0));
        assert!(close(si("100 MN/m^3"), 100e6));
        assert_eq!(dim("100 N/m^3"), Dimension::new(-2, 1, -2, 0));
        assert!(close(si("10 1/s"), 10.0));
        assert_eq!(dim("10 1/s"), dim("10 Hz"));
        // Everything after a slash is in the denominator.
        assert_eq!(dim("1 kg/m/s"), dim("1 Pa s"));
    }

    #[test]
    fn bad_strings_are_rejected() {
        assert!(matches!(
            parse_quantity("abc"),
            Err(UnitError::NotANumber(_))
        ));
        assert!(matches!(parse_quantity(""), Err(UnitError::NotANumber(_))));
        assert!(matches!(parse_quantity("."), Err(UnitError::NotANumber(_))));
        assert!(matches!(
            parse_quantity("NaN Pa"),
            Err(UnitError::NotANumber(_))
        ));
        assert!(matches!(
            parse_quantity("1e999 Pa"),
            Err(UnitError::NotFinite)
        ));
        assert!(matches!(
            parse_quantity("1e308 GPa"),
            Err(UnitError::NotFinite)
        ));
        for bad in [
            "3 furlongs",
            "3 Pa/",
            "3 /m",
            "3 m^",
            "3 m^x",
            "3 m^0",
            "3 xm",
            "3 kdeg",
        ] {
            assert!(
                matches!(parse_quantity(bad), Err(UnitError::UnknownUnit(_))),
                "{bad} was accepted"
            );
        }
        assert_eq!(
            parse_quantity("3 furlongs").unwrap_err().to_string(),
            "unknown unit \"furlongs\""
        );
        assert_eq!(
            parse_quantity("abc").unwrap_err().to_string(),
            "\"abc\" is not a number with a unit (e.g. \"2.5 mm\")"
        );
    }
}
