//! Periodicity along one axis (seed 004 §4: the ballast bed is periodic along the
//! track), shared by the DEM contact search and the NSCD contact detection.

use serde::{Deserialize, Serialize};

/// Periodicity along one axis: the coordinate is taken modulo `length` from `low`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Period {
    /// 0, 1 or 2 for x, y, z.
    pub axis: usize,
    /// Lower end of the periodic cell (m).
    pub low: f64,
    /// Length of the periodic cell (m).
    pub length: f64,
}

impl Period {
    /// The minimum-image difference b − a.
    pub fn difference(period: Option<&Period>, a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        let mut d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        if let Some(p) = period {
            let k = p.axis;
            // The nearest image, without a libm call: the same bits as d − L·round(d/L)
            // while |d| < 1.5 L, which unwrapped positions within the cell always give.
            let half = 0.5 * p.length;
            while d[k] > half {
                d[k] -= p.length;
            }
            while d[k] < -half {
                d[k] += p.length;
            }
        }
        d
    }

    /// `x` (a coordinate along the axis) brought into the cell `[low, low + length)` by
    /// adding or subtracting the length as often as needed (once, for a body that
    /// crossed an end during a step): exact steps of `length`, so the result is the
    /// same on every machine and thread count.
    pub fn wrap(&self, mut x: f64) -> f64 {
        let high = self.low + self.length;
        while x >= high {
            x -= self.length;
        }
        while x < self.low {
            x += self.length;
        }
        x
    }

    /// The translation by `k` lengths along the axis (m).
    pub fn shift(&self, k: i8) -> [f64; 3] {
        let mut t = [0.0; 3];
        t[self.axis] = f64::from(k) * self.length;
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_and_minimum_image() {
        let p = Period {
            axis: 0,
            low: -0.5,
            length: 2.0,
        };
        assert_eq!(p.wrap(1.75), -0.25);
        assert_eq!(p.wrap(-0.75), 1.25);
        assert_eq!(p.wrap(1.5), -0.5);
        assert_eq!(p.wrap(0.25), 0.25);
        let d = Period::difference(Some(&p), [-0.4, 0.0, 0.0], [1.4, 1.0, 0.0]);
        assert!((d[0] + 0.2).abs() < 1e-15 && d[1] == 1.0);
        assert_eq!(p.shift(-1), [-2.0, 0.0, 0.0]);
    }
}
