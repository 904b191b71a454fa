//! Physical checks on a deserialized scene: each scene struct says what it requires
//! (positive density, Poisson ratio below 0.5 …) and the [`Validator`] records the first
//! failures with the dotted key path, e.g. `material.density`.

use std::fmt::Display;

use super::quantity::{format_si, Measure};

/// A scene struct (or part of one) that can check its values after loading.
///
/// ```
/// use ballast::scene::{Length, Validate, Validator};
///
/// struct Beam { length: Length, elements: usize }
///
/// impl Validate for Beam {
///     fn validate(&self, v: &mut Validator) {
///         v.positive("length", self.length);
///         v.check("elements", self.elements > 0, "must be at least 1");
///     }
/// }
///
/// let mut v = Validator::new();
/// Beam { length: Length::from_si(-1.0), elements: 0 }.validate(&mut v);
/// assert_eq!(v.problems()[0], "key length: must be positive, got -1 m");
/// ```
pub trait Validate {
    /// Records every problem of `self` in `v`, with keys relative to `self`.
    fn validate(&self, v: &mut Validator);
}

impl<T: Validate> Validate for Option<T> {
    fn validate(&self, v: &mut Validator) {
        if let Some(inner) = self {
            inner.validate(v);
        }
    }
}

impl<T: Validate> Validate for Box<T> {
    fn validate(&self, v: &mut Validator) {
        (**self).validate(v);
    }
}

/// Collects validation problems, each one line of the form `key a.b.c: reason`.
#[derive(Debug, Default)]
pub struct Validator {
    prefix: Vec<String>,
    problems: Vec<String>,
}

impl Validator {
    /// An empty validator at the root of the scene.
    pub fn new() -> Self {
        Self::default()
    }

    /// The full dotted path of `key` below the current table (`key` may be empty).
    pub fn key_path(&self, key: &str) -> String {
        let mut path = self.prefix.join(".");
        if !key.is_empty() {
            if !path.is_empty() && !key.starts_with('[') {
                path.push('.');
            }
            path.push_str(key);
        }
        path
    }

    /// Records a problem with `key` (relative to the current table).
    pub fn fail(&mut self, key: &str, reason: impl Display) {
        let path = self.key_path(key);
        self.problems.push(format!("key {path}: {reason}"));
    }

    /// Records `reason` for `key` unless `ok`; returns `ok`.
    pub fn check(&mut self, key: &str, ok: bool, reason: impl Display) -> bool {
        if !ok {
            self.fail(key, reason);
        }
        ok
    }

    /// Validates a nested table `key`, so that its keys read `key.inner`.
    pub fn nested<T: Validate + ?Sized>(&mut self, key: &str, value: &T) {
        self.prefix.push(key.to_string());
        value.validate(self);
        self.prefix.pop();
    }

    /// Validates every element of an array of tables, with keys `key[i].inner`.
    pub fn each<T: Validate>(&mut self, key: &str, items: &[T]) {
        for (index, item) in items.iter().enumerate() {
            self.nested(&format!("{key}[{index}]"), item);
        }
    }

    /// Requires a finite value (not NaN nor infinite).
    pub fn finite<M: Measure>(&mut self, key: &str, value: M) -> bool {
        let ok = value.si().is_finite();
        self.check(
            key,
            ok,
            format_args!("must be a finite number, got {}", format_si(value)),
        )
    }

    /// Requires a finite value greater than zero.
    pub fn positive<M: Measure>(&mut self, key: &str, value: M) -> bool {
        self.finite(key, value)
            && self.check(
                key,
                value.si() > 0.0,
                format_args!("must be positive, got {}", format_si(value)),
            )
    }

    /// Requires a finite value greater than or equal to zero.
    pub fn non_negative<M: Measure>(&mut self, key: &str, value: M) -> bool {
        self.finite(key, value)
            && self.check(
                key,
                value.si() >= 0.0,
                format_args!("must not be negative, got {}", format_si(value)),
            )
    }

    /// Requires `low <= value <= high`, bounds in SI units.
    pub fn in_range<M: Measure>(&mut self, key: &str, value: M, low: f64, high: f64) -> bool {
        let unit = M::unit_symbol();
        let unit = if unit.is_empty() {
            String::new()
        } else {
            format!(" {unit}")
        };
        self.finite(key, value)
            && self.check(
                key,
                (low..=high).contains(&value.si()),
                format_args!(
                    "must be between {low} and {high}{unit}, got {}",
                    format_si(value)
                ),
            )
    }

    /// Requires a Poisson ratio of an isotropic, stable elastic solid: -1 < ν < 0.5.
    pub fn poisson(&mut self, key: &str, value: f64) -> bool {
        self.finite(key, value)
            && self.check(
                key,
                value > -1.0 && value < 0.5,
                format_args!(
                    "Poisson ratio must be greater than -1 and less than 0.5, got {value}"
                ),
            )
    }

    /// Every problem recorded so far, in order.
    pub fn problems(&self) -> &[String] {
        &self.problems
    }

    /// `Ok` if nothing was recorded, else one line: the first problem and how many more.
    pub fn finish(self) -> Result<(), String> {
        match self.problems.as_slice() {
            [] => Ok(()),
            [only] => Err(only.clone()),
            [first, rest @ ..] => Err(format!(
                "{first} (and {} more problem{})",
                rest.len(),
                if rest.len() == 1 { "" } else { "s" }
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Density, Length};

    struct Inner {
        size: Length,
    }

    impl Validate for Inner {
        fn validate(&self, v: &mut Validator) {
            v.positive("size", self.size);
        }
    }

    struct Outer {
        inner: Inner,
        items: Vec<Inner>,
        ratio: f64,
    }

    impl Validate for Outer {
        fn validate(&self, v: &mut Validator) {
            v.nested("inner", &self.inner);
            v.each("items", &self.items);
            v.in_range("ratio", self.ratio, 0.0, 1.0);
        }
    }

    #[test]
    fn paths_are_dotted_and_indexed() {
        let outer = Outer {
            inner: Inner {
                size: Length::from_si(0.0),
            },
            items: vec![
                Inner {
                    size: Length::from_si(1.0),
                },
                Inner {
                    size: Length::from_si(-2.0),
                },
            ],
            ratio: 1.5,
        };
        let mut v = Validator::new();
        outer.validate(&mut v);
        assert_eq!(
            v.problems(),
            [
                "key inner.size: must be positive, got 0 m",
                "key items[1].size: must be positive, got -2 m",
                "key ratio: must be between 0 and 1, got 1.5",
            ]
        );
        assert_eq!(
            v.finish().unwrap_err(),
            "key inner.size: must be positive, got 0 m (and 2 more problems)"
        );
    }

    #[test]
    fn helpers_accept_and_reject() {
        let mut v = Validator::new();
        assert!(v.positive("a", Density::from_si(1.0)));
        assert!(v.non_negative("b", 0.0));
        assert!(v.poisson("c", 0.499));
        assert!(v.poisson("c", -0.99));
        assert!(v.in_range("d", 1.0, 0.0, 1.0));
        assert!(v.finish().is_ok());

        let mut v = Validator::new();
        assert!(!v.positive("a", Density::from_si(-2350.0)));
        assert!(!v.non_negative("b", -1e-9));
        assert!(!v.poisson("c", 0.5));
        assert!(!v.poisson("c", -1.0));
        assert!(!v.positive("e", f64::NAN));
        assert!(!v.finite("f", f64::INFINITY));
        assert_eq!(
            v.problems(),
            [
                "key a: must be positive, got -2350 kg/m^3",
                "key b: must not be negative, got -0.000000001",
                "key c: Poisson ratio must be greater than -1 and less than 0.5, got 0.5",
                "key c: Poisson ratio must be greater than -1 and less than 0.5, got -1",
                "key e: must be a finite number, got NaN",
                "key f: must be a finite number, got inf",
            ]
        );
    }
}
