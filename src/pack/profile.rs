//! The cross-section of a track bed: a crest as wide as the sleepers plus a shoulder on
//! each side, at the level of the crib ballast, then the shoulder slopes down to the
//! container's walls (the usual ballast profile: a shoulder of a few tenths of a metre
//! beyond the sleeper ends and a slope of about 1 : 1.5; e.g. Esveld, *Modern Railway
//! Track*, 2nd ed., 2001 — the exact page was not checked here; seed 004 §4's bed is
//! 5 m wide with such slopes).
//!
//! The deposition fills the container and strikes off every stone whose mass centre is
//! above the profile, as a ballast regulator's plough shapes the shoulder; what stays
//! then settles under gravity, so a slope steeper than the stones' friction lets some
//! roll down.

/// A track-bed profile across y (symmetric about y = 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    /// Half-width of the flat top (m): half the sleeper length plus the shoulder width.
    pub crest_half_width: f64,
    /// Horizontal run of the slope per unit of height (1.5 for a 1 : 1.5 slope).
    pub slope: f64,
    /// Level of the flat top (m above the floor): the crib ballast's.
    pub top: f64,
}

impl Profile {
    /// Height of the profile at `y` (m; below zero past the toe).
    pub fn height(&self, y: f64) -> f64 {
        self.top - (y.abs() - self.crest_half_width).max(0.0) / self.slope
    }

    /// Where a fill up to `level` is struck off at `y`: the lower of `level` and the
    /// profile.
    pub fn cap(&self, y: f64, level: f64) -> f64 {
        level.min(self.height(y))
    }

    /// |y| of the slope's toe (the profile reaches the floor there).
    pub fn toe(&self) -> f64 {
        self.half_width_at(0.0)
    }

    /// |y| up to which the profile stands at least `z` high.
    pub fn half_width_at(&self, z: f64) -> f64 {
        self.crest_half_width + self.slope * (self.top - z)
    }

    /// Cross-section area between `bottom` and the fill's cap up to `level`, over
    /// |y| ≤ `half_width` (m²), exactly: the cap is piecewise linear in |y|.
    pub fn section_area(&self, bottom: f64, level: f64, half_width: f64) -> f64 {
        // Breakpoints of (cap − bottom)⁺ on [0, half_width]: the crest edge, where the
        // slope crosses `level`, where it crosses `bottom`.
        let mut knots = vec![0.0, half_width];
        for y in [
            self.crest_half_width,
            self.half_width_at(level),
            self.half_width_at(bottom),
        ] {
            if y > 0.0 && y < half_width {
                knots.push(y);
            }
        }
        knots.sort_by(f64::total_cmp);
        let thickness = |y: f64| (self.cap(y, level) - bottom).max(0.0);
        // Linear between knots: the trapezoid rule is exact.
        2.0 * knots
            .windows(2)
            .map(|w| 0.5 * (w[1] - w[0]) * (thickness(w[0]) + thickness(w[1])))
            .sum::<f64>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile() -> Profile {
        // 2.6 m sleeper, 0.4 m shoulder, 1 : 1.5, crib top at 0.5 m.
        Profile {
            crest_half_width: 1.7,
            slope: 1.5,
            top: 0.5,
        }
    }

    #[test]
    fn height_is_flat_on_the_crest_and_falls_one_in_slope() {
        let p = profile();
        assert_eq!(p.height(0.0), 0.5);
        assert_eq!(p.height(-1.7), 0.5);
        assert!((p.height(2.0) - (0.5 - 0.3 / 1.5)).abs() < 1e-15);
        assert!((p.height(-p.toe())).abs() < 1e-15);
        assert_eq!(p.cap(0.0, 0.3), 0.3);
        assert!((p.cap(2.3, 0.3) - 0.1).abs() < 1e-15);
    }

    #[test]
    fn section_area_is_the_trapezoid() {
        let p = profile();
        // The whole profile: crest rectangle plus two triangles.
        let whole = 2.0 * 1.7 * 0.5 + 1.5 * 0.5 * 0.5;
        assert!((p.section_area(0.0, 0.5, 10.0) - whole).abs() < 1e-12);
        // Cut by walls at |y| = 2: the triangles lose their tips past the wall.
        let tip = 0.5 * (p.toe() - 2.0) * p.height(2.0);
        assert!((p.section_area(0.0, 0.5, 2.0) - (whole - 2.0 * tip)).abs() < 1e-12);
        // A layer between 0.1 and 0.3: trapezoid of height 0.2 with sides on the slope.
        let (lo, hi) = (1.7 + 1.5 * 0.2, 1.7 + 1.5 * 0.4);
        let layer = 0.2 * (lo + hi);
        assert!((p.section_area(0.1, 0.3, 10.0) - layer).abs() < 1e-12);
        // Nothing above the top.
        assert_eq!(p.section_area(0.6, 0.8, 10.0), 0.0);
    }
}
