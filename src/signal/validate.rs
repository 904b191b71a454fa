//! Input checks shared by the signal functions: each failure is one `Error::Message`
//! line naming the function, the argument and what is wrong.

use crate::{Error, Result};

/// The error for a bad argument of `func`.
pub(crate) fn bad(func: &str, what: impl std::fmt::Display) -> Error {
    Error::Message(format!("{func}: {what}"))
}

/// `values` has at least `min_len` entries and all of them are finite.
pub(crate) fn check_series(func: &str, name: &str, values: &[f64], min_len: usize) -> Result<()> {
    if values.is_empty() {
        return Err(bad(func, format!("{name} is empty")));
    }
    if values.len() < min_len {
        return Err(bad(
            func,
            format!(
                "{name} has {} values, at least {min_len} are needed",
                values.len()
            ),
        ));
    }
    if let Some((i, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(bad(func, format!("{name}[{i}] = {v} is not finite")));
    }
    Ok(())
}

/// `value` (a step or width) is finite and strictly positive.
pub(crate) fn check_positive(func: &str, name: &str, value: f64) -> Result<()> {
    if !(value.is_finite() && value > 0.0) {
        return Err(bad(
            func,
            format!("{name} = {value} must be finite and > 0"),
        ));
    }
    Ok(())
}

/// Two series that pair up index by index have the same length.
pub(crate) fn check_same_len(
    func: &str,
    name_a: &str,
    a: &[f64],
    name_b: &str,
    b: &[f64],
) -> Result<()> {
    if a.len() != b.len() {
        return Err(bad(
            func,
            format!(
                "{name_a} has {} values but {name_b} has {}",
                a.len(),
                b.len()
            ),
        ));
    }
    Ok(())
}

/// `values` is strictly increasing (times or frequencies).
pub(crate) fn check_increasing(func: &str, name: &str, values: &[f64]) -> Result<()> {
    if let Some(i) = (1..values.len()).find(|&i| values[i] <= values[i - 1]) {
        return Err(bad(
            func,
            format!(
                "{name} must be strictly increasing, but {name}[{i}] = {} <= {name}[{}] = {}",
                values[i],
                i - 1,
                values[i - 1]
            ),
        ));
    }
    Ok(())
}
